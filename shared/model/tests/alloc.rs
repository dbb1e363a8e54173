//! Every kinematic/dynamic query (and IK) must be allocation-free.

use dkrrt_model::{ArmModel, IkOptions, JVec, NJ};
use dkrrt_rt::alloc_count::{count, CountingAlloc};
use nalgebra::Vector3;
use std::hint::black_box;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn counting_allocator_sees_allocations() {
    // Guards against a vacuous test: the allocator must actually count.
    let (_, s) = count(|| black_box(vec![1u8; 64]));
    assert!(s.allocs >= 1);
}

#[test]
fn queries_do_not_allocate() {
    let mut m = ArmModel::default_arm();
    m.set_gravity(Vector3::new(0.0, 0.0, -9.81));
    let q = JVec::from_column_slice(&[0.3, -0.7, 1.1, 0.4, -0.2, 0.9]);
    let qd = JVec::from_column_slice(&[0.1, 0.05, -0.1, 0.2, -0.15, 0.1]);
    let qdd = JVec::from_column_slice(&[0.5, -0.4, 0.3, 0.2, 0.1, -0.6]);
    let target = m.fk(&JVec::from_column_slice(&[-0.4, 0.5, -0.8, 1.0, 0.6, -0.3]));
    let opts = IkOptions::default();

    let mut pts = [[[0.0; 3]; 2]; NJ];
    let pts = std::cell::RefCell::new(&mut pts);
    let checks: [(&str, &dyn Fn()); 14] = [
        ("fk", &|| {
            black_box(m.fk(black_box(&q)));
        }),
        ("link_poses", &|| {
            black_box(m.link_poses(black_box(&q)));
        }),
        ("capsule_points", &|| {
            m.capsule_points(black_box(&q), &mut pts.borrow_mut()[..]);
        }),
        ("jacobian", &|| {
            black_box(m.jacobian(black_box(&q)));
        }),
        ("fk_jacobian", &|| {
            black_box(m.fk_jacobian(black_box(&q)));
        }),
        ("rnea", &|| {
            black_box(m.rnea(black_box(&q), &qd, &qdd));
        }),
        ("mass_matrix", &|| {
            black_box(m.mass_matrix(black_box(&q)));
        }),
        ("coriolis_matrix", &|| {
            black_box(m.coriolis_matrix(black_box(&q), &qd));
        }),
        ("gravity_torque", &|| {
            black_box(m.gravity_torque(black_box(&q)));
        }),
        ("nonlinear_effects", &|| {
            black_box(m.nonlinear_effects(black_box(&q), &qd));
        }),
        ("forward_dynamics", &|| {
            black_box(m.forward_dynamics(black_box(&q), &qd, &qdd));
        }),
        ("potential_energy", &|| {
            black_box(m.potential_energy(black_box(&q)));
        }),
        ("collision_capsules", &|| {
            black_box(m.collision_capsules());
        }),
        ("ik", &|| {
            black_box(m.ik(black_box(&target), &q, &opts).expect("reachable"));
        }),
    ];
    for (name, f) in checks {
        f(); // warm up (lazy statics etc.)
        let (_, s) = count(f);
        assert_eq!(s.allocs + s.reallocs, 0, "{name} allocated: {s:?}");
    }
    // Unreachable IK (all restarts exhausted) does not allocate either.
    let far = nalgebra::Isometry3::translation(9.0, 0.0, 0.0);
    let ((), s) = count(|| {
        black_box(m.ik(&far, &q, &IkOptions { restarts: 2, ..opts }).unwrap_err());
    });
    assert_eq!(s.allocs, 0, "unreachable ik allocated: {s:?}");
}
