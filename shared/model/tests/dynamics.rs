//! Dynamics identities on many seeded random states, for the shipped arm and
//! random URDF arms (arbitrary rpy/axes, merged fixed links).

mod common;

use common::{models, random_q, random_vec, rel, rng, rot_rate};
use dkrrt_model::{ArmModel, JMat, JVec, NJ};
use nalgebra::{Matrix3, SMatrix, Vector3};

const STATES: usize = 40;
const G_GROUND: Vector3<f64> = Vector3::new(0.4, -1.3, -9.81);

#[test]
fn rnea_equals_m_qdd_plus_c_qd_plus_g() {
    for g in [Vector3::zeros(), G_GROUND] {
        for (name, m) in models(g) {
            let mut r = rng(1);
            for _ in 0..STATES {
                let (q, qd, qdd) = (random_q(&m, &mut r), random_vec(&mut r, 1.0), random_vec(&mut r, 2.0));
                let tau = m.rnea(&q, &qd, &qdd);
                let rhs = m.mass_matrix(&q) * qdd + m.coriolis_matrix(&q, &qd) * qd + m.gravity_torque(&q);
                assert!(rel(&tau, &rhs) < 1e-11, "{name}: rnea {tau} vs {rhs}");
                let nle = m.nonlinear_effects(&q, &qd);
                assert!(rel(&nle, &(m.coriolis_matrix(&q, &qd) * qd + m.gravity_torque(&q))) < 1e-11);
            }
        }
    }
}

#[test]
fn mass_matrix_is_symmetric_positive_definite() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(2);
        for _ in 0..STATES {
            let q = random_q(&m, &mut r);
            let mm = m.mass_matrix(&q);
            assert!((mm - mm.transpose()).norm() <= 1e-12 * mm.norm(), "{name}: not symmetric");
            let eig = mm.symmetric_eigen().eigenvalues;
            assert!(eig.min() > 1e-6, "{name}: eigenvalues {eig}");
        }
    }
}

#[test]
fn mass_matrix_columns_are_rnea_of_unit_accelerations() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(3);
        for _ in 0..10 {
            let q = random_q(&m, &mut r);
            let mm = m.mass_matrix(&q);
            for k in 0..NJ {
                let col = m.rnea(&q, &JVec::zeros(), &JVec::ith(k, 1.0));
                assert!(rel(&col, &mm.column(k).into_owned()) < 1e-12, "{name} col {k}");
            }
        }
    }
}

/// Independent cross-check: M = Σ_b J_vᵀ m J_v + J_ωᵀ (R I_c Rᵀ) J_ω with the
/// centre-of-mass Jacobians obtained by finite differences of `link_poses` and the
/// inertial parameters from `link_inertials` (no spatial algebra involved).
#[test]
fn mass_matrix_matches_sum_of_link_jacobians() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(4);
        let eps = 1e-6;
        for _ in 0..10 {
            let q = random_q(&m, &mut r);
            let poses = m.link_poses(&q);
            let mut plus = Vec::new();
            let mut minus = Vec::new();
            for k in 0..NJ {
                plus.push(m.link_poses(&(q + JVec::ith(k, eps))));
                minus.push(m.link_poses(&(q - JVec::ith(k, eps))));
            }
            let mut expect = JMat::zeros();
            for (b, inl) in m.link_inertials().iter().enumerate() {
                let mut jv = SMatrix::<f64, 3, NJ>::zeros();
                let mut jw = SMatrix::<f64, 3, NJ>::zeros();
                for k in 0..NJ {
                    let cp = plus[k][b] * nalgebra::Point3::from(inl.com);
                    let cm = minus[k][b] * nalgebra::Point3::from(inl.com);
                    jv.set_column(k, &((cp - cm) / (2.0 * eps)));
                    jw.set_column(k, &rot_rate(&plus[k][b], &minus[k][b], 2.0 * eps));
                }
                let rm: Matrix3<f64> = *poses[b].rotation.to_rotation_matrix().matrix();
                let iw = rm * inl.inertia * rm.transpose();
                expect += jv.transpose() * jv * inl.mass + jw.transpose() * iw * jw;
            }
            let got = m.mass_matrix(&q);
            assert!(rel(&got, &expect) < 1e-7, "{name}: M\n{got}\nexpected\n{expect}");
        }
    }
}

#[test]
fn mdot_minus_2c_is_skew_symmetric() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(5);
        let eps = 1e-6;
        for _ in 0..STATES {
            let (q, qd) = (random_q(&m, &mut r), random_vec(&mut r, 1.0));
            // Ṁ = dM/dt along q̇, central difference.
            let mdot = (m.mass_matrix(&(q + qd * eps)) - m.mass_matrix(&(q - qd * eps))) / (2.0 * eps);
            let c = m.coriolis_matrix(&q, &qd);
            let n = mdot - 2.0 * c;
            let scale = 1.0 + mdot.norm() + c.norm();
            // Guard against a vacuous test: Ṁ must be substantial here.
            assert!(mdot.norm() > 1e-3, "{name}: Ṁ too small to test");
            assert!(
                (n + n.transpose()).norm() < 1e-7 * scale,
                "{name}: Ṁ − 2C not skew:\n{}",
                n + n.transpose()
            );
        }
    }
}

/// The returned C is exactly the Christoffel-symbol construction
/// C_ij = Σ_k ½(∂M_ij/∂q_k + ∂M_ik/∂q_j − ∂M_jk/∂q_i) q̇_k with ∂M/∂q by finite differences.
#[test]
fn coriolis_matrix_equals_christoffel_symbols() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(6);
        let eps = 1e-6;
        for _ in 0..10 {
            let (q, qd) = (random_q(&m, &mut r), random_vec(&mut r, 1.0));
            let dm: Vec<JMat> = (0..NJ)
                .map(|k| {
                    (m.mass_matrix(&(q + JVec::ith(k, eps))) - m.mass_matrix(&(q - JVec::ith(k, eps))))
                        / (2.0 * eps)
                })
                .collect();
            let christoffel = JMat::from_fn(|i, j| {
                (0..NJ).map(|k| 0.5 * (dm[k][(i, j)] + dm[j][(i, k)] - dm[i][(j, k)]) * qd[k]).sum()
            });
            let c = m.coriolis_matrix(&q, &qd);
            assert!(rel(&c, &christoffel) < 1e-7, "{name}: C\n{c}\nChristoffel\n{christoffel}");
        }
    }
}

#[test]
fn forward_dynamics_inverts_rnea() {
    for g in [Vector3::zeros(), G_GROUND] {
        for (name, m) in models(g) {
            let mut r = rng(7);
            for _ in 0..STATES {
                let (q, qd, qdd) = (random_q(&m, &mut r), random_vec(&mut r, 1.0), random_vec(&mut r, 2.0));
                let back = m.forward_dynamics(&q, &qd, &m.rnea(&q, &qd, &qdd));
                assert!(rel(&back, &qdd) < 1e-9, "{name}: fd(rnea(qdd)) = {back} vs {qdd}");
                let tau = random_vec(&mut r, 50.0);
                let again = m.rnea(&q, &qd, &m.forward_dynamics(&q, &qd, &tau));
                assert!(rel(&again, &tau) < 1e-9, "{name}: rnea(fd(tau))");
            }
        }
    }
}

#[test]
fn gravity_matches_rnea_at_rest_and_potential_gradient() {
    for (name, m) in models(G_GROUND) {
        let mut r = rng(8);
        let eps = 1e-6;
        for _ in 0..STATES {
            let q = random_q(&m, &mut r);
            let g = m.gravity_torque(&q);
            assert!(g.norm() > 1.0, "{name}: gravity torque suspiciously small");
            assert!(rel(&g, &m.rnea(&q, &JVec::zeros(), &JVec::zeros())) < 1e-12);
            let grad = JVec::from_fn(|k, _| {
                (m.potential_energy(&(q + JVec::ith(k, eps))) - m.potential_energy(&(q - JVec::ith(k, eps))))
                    / (2.0 * eps)
            });
            assert!(rel(&g, &grad) < 1e-7, "{name}: g {g} vs ∇U {grad}");
            // Potential energy cross-checked from link poses and link inertials.
            let poses = m.link_poses(&q);
            let u: f64 = m
                .link_inertials()
                .iter()
                .zip(poses.iter())
                .map(|(l, p)| -l.mass * G_GROUND.dot(&(p * nalgebra::Point3::from(l.com)).coords))
                .sum();
            assert!((u - m.potential_energy(&q)).abs() < 1e-9 * (1.0 + u.abs()), "{name}: U");
        }
    }
}

#[test]
fn zero_gravity_by_default_and_in_orbit_no_static_torque() {
    let m = ArmModel::default_arm();
    assert_eq!(*m.gravity(), Vector3::zeros());
    let mut r = rng(9);
    let q = random_q(&m, &mut r);
    assert_eq!(m.gravity_torque(&q), JVec::zeros());
    assert!(m.rnea(&q, &JVec::zeros(), &JVec::zeros()).norm() < 1e-12);
}

/// Power balance in orbit: d/dt(½ q̇ᵀ M q̇) = q̇ᵀ τ along a trajectory.
#[test]
fn kinetic_energy_rate_equals_joint_power() {
    for (name, m) in models(Vector3::zeros()) {
        let mut r = rng(10);
        let h = 1e-6;
        for _ in 0..10 {
            let (q, qd, qdd) = (random_q(&m, &mut r), random_vec(&mut r, 1.0), random_vec(&mut r, 2.0));
            let tau = m.rnea(&q, &qd, &qdd);
            let ke = |t: f64| m.kinetic_energy(&(q + qd * t + qdd * (0.5 * t * t)), &(qd + qdd * t));
            let rate = (ke(h) - ke(-h)) / (2.0 * h);
            let power = qd.dot(&tau);
            assert!((rate - power).abs() < 1e-6 * (1.0 + power.abs()), "{name}: {rate} vs {power}");
        }
    }
}

#[test]
fn clone_gives_identical_results() {
    let m = ArmModel::default_arm();
    let c = m.clone();
    let mut r = rng(11);
    let (q, qd, qdd) = (random_q(&m, &mut r), random_vec(&mut r, 1.0), random_vec(&mut r, 1.0));
    assert_eq!(m.rnea(&q, &qd, &qdd), c.rnea(&q, &qd, &qdd));
    assert_eq!(m.fk(&q), c.fk(&q));
}
