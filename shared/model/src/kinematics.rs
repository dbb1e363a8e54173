//! Forward kinematics and the geometric Jacobian.

use nalgebra::{Isometry3, Matrix3, Rotation3, SMatrix, Translation3, UnitQuaternion, Vector3};

use crate::model::ArmModel;
use crate::spatial::mul_rz;
use crate::{JVec, NJ};

/// Geometric Jacobian of the end effector: `6 x NJ`.
///
/// Rows 0..3 are the **linear** velocity of the end-effector origin and rows
/// 3..6 the **angular** velocity of the end-effector frame, both in base-frame
/// coordinates: `[ṗ; ω] = J(q) q̇`.
pub type Jacobian = SMatrix<f64, 6, NJ>;

/// Pose of every body (internal frame) in the base frame: rotations and origins.
#[derive(Clone, Copy)]
pub(crate) struct BodyFrames {
    pub r: [Matrix3<f64>; NJ],
    pub p: [Vector3<f64>; NJ],
}

pub(crate) fn iso(r: &Matrix3<f64>, p: &Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(*p),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r)),
    )
}

impl ArmModel {
    /// Base-frame poses of the internal body frames.
    #[inline]
    pub(crate) fn body_frames(&self, q: &JVec) -> BodyFrames {
        let mut r = [Matrix3::identity(); NJ];
        let mut p = [Vector3::zeros(); NJ];
        let mut rp = Matrix3::identity();
        let mut pp = Vector3::zeros();
        for i in 0..NJ {
            p[i] = pp + rp * self.pc[i];
            r[i] = mul_rz(&(rp * self.rc[i]), q[i]);
            rp = r[i];
            pp = p[i];
        }
        BodyFrames { r, p }
    }

    /// End-effector rotation and position from body frames.
    #[inline]
    pub(crate) fn ee_from_frames(&self, f: &BodyFrames) -> (Matrix3<f64>, Vector3<f64>) {
        let (r, p) = (&f.r[NJ - 1], &f.p[NJ - 1]);
        (r * self.ee_rot, p + r * self.ee_pos)
    }

    /// Jacobian from body frames and the end-effector position.
    #[inline]
    pub(crate) fn jacobian_from_frames(&self, f: &BodyFrames, p_ee: &Vector3<f64>) -> Jacobian {
        let mut j = Jacobian::zeros();
        for k in 0..NJ {
            let z = f.r[k].column(2).into_owned();
            let lin = z.cross(&(p_ee - f.p[k]));
            j.fixed_view_mut::<3, 1>(0, k).copy_from(&lin);
            j.fixed_view_mut::<3, 1>(3, k).copy_from(&z);
        }
        j
    }

    /// Forward kinematics: pose of the end-effector frame in the base frame.
    pub fn fk(&self, q: &JVec) -> Isometry3<f64> {
        let f = self.body_frames(q);
        let (r, p) = self.ee_from_frames(&f);
        iso(&r, &p)
    }

    /// Poses (in the base frame) of the URDF frames of the moving links, i.e. the
    /// child link of each actuated joint, base to tip.
    pub fn link_poses(&self, q: &JVec) -> [Isometry3<f64>; NJ] {
        let f = self.body_frames(q);
        std::array::from_fn(|i| iso(&(f.r[i] * self.to_link[i]), &f.p[i]))
    }

    /// Base-frame end points of the collision capsules at `q`, in the order of
    /// [`ArmModel::collision_capsules`] (`out` holds as many): the links' rotation matrices
    /// applied directly, no quaternion per link as [`ArmModel::link_poses`] builds (the
    /// collision checks' hot path). Allocation-free.
    pub fn capsule_points(&self, q: &JVec, out: &mut [[[f64; 3]; 2]]) {
        let f = self.body_frames(q);
        for (o, lc) in out.iter_mut().zip(self.collision_capsules()) {
            let (r, p, tl) = (&f.r[lc.link], &f.p[lc.link], &self.to_link[lc.link]);
            let (a, b) = (r * (tl * lc.a.coords) + p, r * (tl * lc.b.coords) + p);
            *o = [[a.x, a.y, a.z], [b.x, b.y, b.z]];
        }
    }

    /// Base-frame joint axes (unit) and the points they pass through (joint origins).
    pub fn joint_axes(&self, q: &JVec) -> [(Vector3<f64>, Vector3<f64>); NJ] {
        let f = self.body_frames(q);
        std::array::from_fn(|i| (f.r[i].column(2).into_owned(), f.p[i]))
    }

    /// Geometric Jacobian of the end-effector frame (see [`Jacobian`] for the
    /// `[linear; angular]`, base-frame convention).
    pub fn jacobian(&self, q: &JVec) -> Jacobian {
        let f = self.body_frames(q);
        let (_, p) = self.ee_from_frames(&f);
        self.jacobian_from_frames(&f, &p)
    }

    /// End-effector pose and Jacobian in one pass (cheaper than calling both).
    pub fn fk_jacobian(&self, q: &JVec) -> (Isometry3<f64>, Jacobian) {
        let f = self.body_frames(q);
        let (r, p) = self.ee_from_frames(&f);
        (iso(&r, &p), self.jacobian_from_frames(&f, &p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_arm_zero_pose_is_stretched_along_x() {
        let m = ArmModel::default_arm();
        let t = m.fk(&JVec::zeros());
        // base 0.25 + shoulder 0.20 in z; x: 1.10 + 1.00 + 0.20 + 0.20 + 0.25 + 0.15;
        // y offsets +0.22 − 0.22 + 0.22.
        let p = t.translation.vector;
        assert!((p - Vector3::new(2.90, 0.22, 0.45)).norm() < 1e-12, "{p}");
        assert!(t.rotation.angle() < 1e-12);
    }

    #[test]
    fn shoulder_yaw_rotates_the_whole_arm_about_base_z() {
        let m = ArmModel::default_arm();
        let mut q = JVec::zeros();
        q[0] = std::f64::consts::FRAC_PI_2;
        let p = m.fk(&q).translation.vector;
        assert!((p - Vector3::new(-0.22, 2.90, 0.45)).norm() < 1e-12, "{p}");
    }
}
