//! Kinematics: Jacobian against finite differences of FK, frame consistency.

mod common;

use common::{models, random_q, rng, rot_rate};
use dkrrt_model::{ArmModel, JVec, NJ};
use nalgebra::{Point3, Vector3};

#[test]
fn jacobian_matches_finite_difference_of_fk() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(21);
        let eps = 1e-6;
        for _ in 0..40 {
            let q = random_q(&m, &mut r);
            let j = m.jacobian(&q);
            for k in 0..NJ {
                let (tp, tm) = (m.fk(&(q + JVec::ith(k, eps))), m.fk(&(q - JVec::ith(k, eps))));
                let lin = (tp.translation.vector - tm.translation.vector) / (2.0 * eps);
                let ang = rot_rate(&tp, &tm, 2.0 * eps);
                let jl = j.fixed_view::<3, 1>(0, k).into_owned();
                let ja = j.fixed_view::<3, 1>(3, k).into_owned();
                assert!(
                    (jl - lin).norm() < 1e-7 * (1.0 + lin.norm()),
                    "{name} linear col {k}: {jl} vs {lin}"
                );
                assert!((ja - ang).norm() < 1e-7, "{name} angular col {k}: {ja} vs {ang}");
            }
            let (pose, j2) = m.fk_jacobian(&q);
            assert_eq!(pose, m.fk(&q));
            assert_eq!(j2, j);
        }
    }
}

#[test]
fn link_poses_are_consistent_with_joint_axes_and_fk() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(22);
        for _ in 0..20 {
            let q = random_q(&m, &mut r);
            let poses = m.link_poses(&q);
            let axes = m.joint_axes(&q);
            for k in 0..NJ {
                // Each link frame origin is its joint origin, and rotating joint k moves
                // link k about the joint axis: a point on the axis stays put.
                assert!((poses[k].translation.vector - axes[k].1).norm() < 1e-12, "{name}");
                let on_axis = Point3::from(axes[k].1 + axes[k].0 * 0.7);
                let local = poses[k].inverse() * on_axis;
                let moved = m.link_poses(&(q + JVec::ith(k, 0.3)))[k] * local;
                assert!((moved - on_axis).norm() < 1e-12, "{name}: joint {k} axis");
                // Links before k do not move.
                let after = m.link_poses(&(q + JVec::ith(k, 0.3)));
                for (before, moved) in poses.iter().zip(after.iter()).take(k) {
                    assert!(before.translation.vector == moved.translation.vector, "{name}");
                    assert!(before.rotation == moved.rotation, "{name}");
                }
            }
            // Moving the last joint does not change the EE distance to its axis.
            let (a, p) = axes[NJ - 1];
            let d = |t: &nalgebra::Isometry3<f64>| (t.translation.vector - p).cross(&a).norm();
            let t0 = m.fk(&q);
            let t1 = m.fk(&(q + JVec::ith(NJ - 1, 1.0)));
            assert!((d(&t0) - d(&t1)).abs() < 1e-12);
        }
    }
}

#[test]
fn capsule_points_are_the_link_poses_capsule_segments() {
    // The collision hot path's end points (rotation matrices throughout) are the capsules'
    // segments placed by the link poses (quaternions), to rounding.
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(23);
        let n = m.collision_capsules().len();
        assert!(n > 0, "{name}");
        let mut pts = vec![[[0.0; 3]; 2]; n];
        for _ in 0..50 {
            let q = random_q(&m, &mut r);
            let poses = m.link_poses(&q);
            m.capsule_points(&q, &mut pts);
            for (lc, [a, b]) in m.collision_capsules().iter().zip(&pts) {
                let (wa, wb) = lc.world_segment(&poses[lc.link]);
                let d = (Vector3::from(*a) - wa.coords).norm() + (Vector3::from(*b) - wb.coords).norm();
                assert!(d < 1e-12, "{name}: link {} off by {d}", lc.link);
            }
        }
    }
}

#[test]
fn default_arm_capsules_follow_the_links() {
    let m = ArmModel::default_arm();
    let caps = m.collision_capsules();
    for (i, c) in caps.iter().enumerate() {
        assert_eq!(c.link, i);
        assert!(c.radius >= 0.09 && c.radius <= 0.15);
    }
    // Upper boom capsule runs along the boom x axis from −0.1 to 1.2 m.
    let ub = caps[1];
    let (a, b) = (ub.a.coords, ub.b.coords);
    let (lo, hi) = if a.x < b.x { (a, b) } else { (b, a) };
    assert!((lo - Vector3::new(-0.1, 0.0, 0.0)).norm() < 1e-12, "{lo}");
    assert!((hi - Vector3::new(1.2, 0.0, 0.0)).norm() < 1e-12, "{hi}");
    // At q = 0 the wrist-roll capsule covers the tool point (EE frame origin).
    let q = JVec::zeros();
    let poses = m.link_poses(&q);
    let (wa, wb) = caps[5].world_segment(&poses[5]);
    let tool = Point3::from(m.fk(&q).translation.vector);
    let seg = wb - wa;
    let t = ((tool - wa).dot(&seg) / seg.norm_squared()).clamp(0.0, 1.0);
    assert!((wa + seg * t - tool).norm() < 1e-12);
}

#[test]
fn default_arm_is_non_degenerate() {
    let m = ArmModel::default_arm();
    let mut r = rng(23);
    // Full rank Jacobian at random configurations (not all axes parallel, has a wrist).
    let mut full_rank = 0;
    for _ in 0..50 {
        let q = random_q(&m, &mut r);
        let sv = m.jacobian(&q).singular_values();
        if sv.min() > 1e-3 {
            full_rank += 1;
        }
    }
    assert!(full_rank >= 45, "only {full_rank}/50 random configurations have a full-rank Jacobian");
    let total = m.total_mass();
    assert!((total - 112.0).abs() < 1e-9, "{total}");
}
