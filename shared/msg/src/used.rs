//! The part of a message that its counts use.
//!
//! The large payloads are fixed-size arrays with a count: a trajectory's `n_seg` segments per
//! joint (of 72), a forecast's `count` tracks (of 32) with `steps` steps each (of 40), an
//! observation frame's `count` items (of 32). Nothing reads beyond the counts (validation,
//! sampling, the planner's world, the recorder), so the bus copies only the used part into a
//! loaned sample and out of a received one: a 7-segment trajectory moves 1.7 kB instead of
//! 17 kB, a 6-track forecast 17 kB instead of 94 kB. What lies beyond the counts in a copy is
//! whatever its memory held before (the receiver's earlier messages, or an earlier sample in
//! the shared memory): never part of the message.

use core::mem::{offset_of, size_of};
use core::ptr::copy_nonoverlapping;

use crate::types::*;

/// What a payload's counts use, and a copy of just that.
pub trait UsedPart: Sized + Copy {
    /// Writes the header, the scalar fields and the counted items of `self` into `dst`; the
    /// rest of `dst` is left as it was. The default copies everything.
    ///
    /// # Safety
    /// `dst` is valid for writes of one `Self` and aligned.
    unsafe fn write_used(&self, dst: *mut Self) {
        // SAFETY: the caller's promise; `self` is a valid `Self`.
        unsafe { copy_nonoverlapping(self, dst, 1) }
    }

    /// Bytes [`UsedPart::write_used`] copies.
    fn used_bytes(&self) -> usize {
        size_of::<Self>()
    }
}

/// Copies the first `n` bytes of `src` to `dst` (the fields before a payload's counted array).
///
/// # Safety
/// `dst` is valid for writes of one `T`; `n ≤ size_of::<T>()`.
unsafe fn copy_prefix<T>(src: &T, dst: *mut T, n: usize) {
    // SAFETY: both are valid for `n ≤ size_of::<T>()` bytes and do not overlap (`dst` is
    // another message); an untyped copy carries padding bytes as they are.
    unsafe { copy_nonoverlapping((src as *const T).cast::<u8>(), dst.cast::<u8>(), n) }
}

impl UsedPart for Trajectory {
    unsafe fn write_used(&self, dst: *mut Self) {
        // SAFETY: `dst` is valid for one Trajectory (the caller's promise); the prefix ends
        // where `seg` starts, and each joint's first `n` segments lie within `seg[j]`.
        unsafe {
            copy_prefix(self, dst, offset_of!(Trajectory, seg));
            let seg = dst.cast::<u8>().add(offset_of!(Trajectory, seg)).cast::<[JerkSegment; MAX_SEGMENTS]>();
            for j in 0..NJ {
                let n = (self.n_seg[j] as usize).min(MAX_SEGMENTS);
                copy_nonoverlapping(self.seg[j].as_ptr(), seg.add(j).cast::<JerkSegment>(), n);
            }
        }
    }

    fn used_bytes(&self) -> usize {
        let segs: usize = self.n_seg.iter().map(|&n| (n as usize).min(MAX_SEGMENTS)).sum();
        offset_of!(Trajectory, seg) + segs * size_of::<JerkSegment>()
    }
}

impl UsedPart for DebrisForecast {
    unsafe fn write_used(&self, dst: *mut Self) {
        let steps = (self.steps as usize).min(FORECAST_STEPS);
        // SAFETY: `dst` is valid for one DebrisForecast; each of the first `count` tracks
        // lies within `tracks`, its prefix ends where its `steps` start, and `steps ≤
        // FORECAST_STEPS` of them lie within its `steps`.
        unsafe {
            copy_prefix(self, dst, offset_of!(DebrisForecast, tracks));
            let tracks = dst.cast::<u8>().add(offset_of!(DebrisForecast, tracks)).cast::<ForecastTrack>();
            for (i, tr) in self.tracks.iter().take((self.count as usize).min(MAX_DEBRIS)).enumerate() {
                let out = tracks.add(i);
                copy_prefix(tr, out, offset_of!(ForecastTrack, steps));
                let st = out.cast::<u8>().add(offset_of!(ForecastTrack, steps)).cast::<ForecastStep>();
                copy_nonoverlapping(tr.steps.as_ptr(), st, steps);
            }
        }
    }

    fn used_bytes(&self) -> usize {
        let tracks = (self.count as usize).min(MAX_DEBRIS);
        let steps = (self.steps as usize).min(FORECAST_STEPS);
        offset_of!(DebrisForecast, tracks)
            + tracks * (offset_of!(ForecastTrack, steps) + steps * size_of::<ForecastStep>())
    }
}

impl UsedPart for DebrisObservation {
    unsafe fn write_used(&self, dst: *mut Self) {
        let n = (self.count as usize).min(MAX_DEBRIS);
        // SAFETY: `dst` is valid for one frame; the prefix ends where `items` starts, and
        // `n ≤ MAX_DEBRIS` items lie within it.
        unsafe {
            copy_prefix(self, dst, offset_of!(DebrisObservation, items));
            let items = dst.cast::<u8>().add(offset_of!(DebrisObservation, items)).cast::<DebrisObs>();
            copy_nonoverlapping(self.items.as_ptr(), items, n);
        }
    }

    fn used_bytes(&self) -> usize {
        offset_of!(DebrisObservation, items) + (self.count as usize).min(MAX_DEBRIS) * size_of::<DebrisObs>()
    }
}

impl UsedPart for RobotState {}
impl UsedPart for TorqueCommand {}
impl UsedPart for Goal {}
impl UsedPart for Heartbeat {}
impl UsedPart for PlanStatus {}
impl UsedPart for PredictorProgress {}
impl UsedPart for DepthImage {}

// The counted arrays are their types' last fields: the prefixes above hold everything else.
const _: () = {
    assert!(
        offset_of!(Trajectory, seg) + size_of::<[[JerkSegment; MAX_SEGMENTS]; NJ]>()
            == size_of::<Trajectory>()
    );
    assert!(
        offset_of!(DebrisForecast, tracks) + size_of::<[ForecastTrack; MAX_DEBRIS]>()
            == size_of::<DebrisForecast>()
    );
    assert!(
        offset_of!(ForecastTrack, steps) + size_of::<[ForecastStep; FORECAST_STEPS]>()
            == size_of::<ForecastTrack>()
    );
    assert!(
        offset_of!(DebrisObservation, items) + size_of::<[DebrisObs; MAX_DEBRIS]>()
            == size_of::<DebrisObservation>()
    );
};
