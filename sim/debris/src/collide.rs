//! Arm-link proximity / contact queries against the debris (parry3d, allocation-free).

use crate::world::Debris;
use parry3d_f64::glamx::DQuat;
use parry3d_f64::math::{Pose, Vector as PVec};
use parry3d_f64::query;
use parry3d_f64::shape::Capsule;

/// An arm link as a capsule: segment endpoints in LVLH [m] and radius [m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkCapsule {
    /// First endpoint (LVLH).
    pub a: [f64; 3],
    /// Second endpoint (LVLH).
    pub b: [f64; 3],
    /// Radius [m].
    pub radius: f64,
}

/// A capsule–debris pair closer than the contact margin.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactPair {
    /// Index into the capsule list.
    pub capsule: usize,
    /// Debris id.
    pub debris_id: u32,
    /// Separation distance (0 when touching/overlapping) [m].
    pub distance: f64,
}

/// Result of [`proximity`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// Minimum separation over all capsule–debris pairs (`f64::INFINITY` if there are none) [m].
    pub min_distance: f64,
    /// Capsule index of the closest pair.
    pub capsule: usize,
    /// Debris id of the closest pair.
    pub debris_id: u32,
    /// Number of pairs with distance ≤ margin (may exceed the output buffer length).
    pub n_contacts: usize,
}

impl Proximity {
    /// True when at least one pair is within the margin.
    pub fn any_contact(&self) -> bool {
        self.n_contacts > 0
    }
}

fn seg_point_dist(a: &PVec, b: &PVec, p: &PVec) -> f64 {
    let ab = *b - *a;
    let l2 = ab.length_squared();
    let s = if l2 > 0.0 { ((*p - *a).dot(ab) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (*a + ab * s - *p).length()
}

/// Pose of a debris object as a parry pose.
pub fn debris_pose(d: &Debris) -> Pose {
    let q = d.state.q.quaternion();
    let rot = DQuat::from_xyzw(q.i, q.j, q.k, q.w);
    Pose::from_parts(PVec::new(d.state.p.x, d.state.p.y, d.state.p.z), rot)
}

/// Minimum distance and contacts between link capsules and all debris.
///
/// Pairs with separation ≤ `margin` are written to `contacts` (up to its length; the total
/// count is in [`Proximity::n_contacts`]). A bounding-sphere test skips exact (GJK) queries that
/// cannot beat the current minimum or reach the margin. Allocation-free.
pub fn proximity(
    debris: &[Debris],
    capsules: &[LinkCapsule],
    margin: f64,
    contacts: &mut [ContactPair],
) -> Proximity {
    let mut out = Proximity { min_distance: f64::INFINITY, capsule: 0, debris_id: u32::MAX, n_contacts: 0 };
    let identity = Pose::IDENTITY;
    for (ci, c) in capsules.iter().enumerate() {
        let a = PVec::new(c.a[0], c.a[1], c.a[2]);
        let b = PVec::new(c.b[0], c.b[1], c.b[2]);
        let cap = Capsule::new(a, b, c.radius);
        for d in debris {
            let centre = PVec::new(d.state.p.x, d.state.p.y, d.state.p.z);
            let lower = seg_point_dist(&a, &b, &centre) - c.radius - d.props.bounding_radius;
            if lower > out.min_distance && lower > margin {
                continue;
            }
            let dist = match query::distance(&debris_pose(d), d.props.shape.as_ref(), &identity, &cap) {
                Ok(r) => r.distance,
                Err(_) => lower.max(0.0), // unsupported pair: conservative bound
            };
            if dist < out.min_distance {
                out.min_distance = dist;
                out.capsule = ci;
                out.debris_id = d.id;
            }
            if dist <= margin {
                if out.n_contacts < contacts.len() {
                    contacts[out.n_contacts] = ContactPair { capsule: ci, debris_id: d.id, distance: dist };
                }
                out.n_contacts += 1;
            }
        }
    }
    out
}
