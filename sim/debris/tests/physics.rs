//! Physics validation: torque-free tumbling invariants, relative orbit vs closed forms.

use dkrrt_debris::body::rotational_energy;
use dkrrt_debris::orbit::{clohessy_wiltshire, kepler_to_eci, OrbitConfig, RefOrbit, MU_EARTH};
use dkrrt_debris::{DebrisSpec, DebrisWorld, Scene, ShapeSpec};
use nalgebra::Vector3;

fn one_body_scene(orbit: OrbitConfig, shape: ShapeSpec, p: [f64; 3], v: [f64; 3], w: [f64; 3]) -> Scene {
    Scene {
        name: "test".into(),
        seed: 0,
        orbit,
        integrator: Default::default(),
        perturbation: Default::default(),
        debris: vec![DebrisSpec {
            id: 7,
            shape,
            mass: 10.0,
            inertia: None,
            p,
            v,
            q: [0.8, 0.2, -0.4, 0.4],
            w,
        }],
        events: vec![],
    }
}

#[test]
fn torque_free_tumbling_conserves_energy_and_inertial_angular_momentum() {
    // Asymmetric box spun close to its intermediate axis: a genuinely tumbling motion.
    let shape = ShapeSpec::Box { half_extents: [0.6, 0.3, 0.1] };
    let orbit = OrbitConfig { inclination_deg: 51.6, eccentricity: 0.01, ..Default::default() };
    let mut world =
        DebrisWorld::new(&one_body_scene(orbit, shape, [2.0, 0.0, 0.0], [0.0; 3], [0.02, 1.0, 0.03]))
            .unwrap();
    world.set_max_substep(0.005);
    let props = world.debris()[0].props.clone();
    let i = props.inertia;
    assert!(
        (i[(0, 0)] - i[(1, 1)]).abs() > 0.1 * i[(0, 0)] && (i[(1, 1)] - i[(2, 2)]).abs() > 0.1 * i[(1, 1)]
    );
    let e0 = rotational_energy(&props, &world.debris()[0].state.w);
    let h0 = world.angular_momentum_eci(0);
    let w0 = world.debris()[0].state.w;
    let mut max_dw: f64 = 0.0;
    for _ in 0..400 {
        world.step(0.1);
        max_dw = max_dw.max((world.debris()[0].state.w - w0).norm());
        let e = rotational_energy(&props, &world.debris()[0].state.w);
        let h = world.angular_momentum_eci(0);
        assert!(((e - e0) / e0).abs() < 1e-9, "energy drift {}", (e - e0) / e0);
        assert!((h - h0).norm() / h0.norm() < 1e-8, "angular momentum drift {}", (h - h0).norm() / h0.norm());
    }
    // The body rate really changed (intermediate-axis instability), so the test is not trivial.
    assert!(max_dw > 0.5, "body rate barely changed: {max_dw}");
    // The LVLH attitude differs from the inertial one: the frame rotated by ~n·40 s.
    assert!((world.debris()[0].state.q.norm() - 1.0).abs() < 1e-12);
}

fn cw_error(scale: f64, t_end: f64) -> f64 {
    let orbit = OrbitConfig { inclination_deg: 0.0, ..Default::default() };
    let p0 = Vector3::new(1.0, 0.5, -0.3) * scale;
    let v0 = Vector3::new(0.4e-3, -1.1e-3, 0.6e-3) * scale;
    let mut world = DebrisWorld::new(&one_body_scene(
        orbit,
        ShapeSpec::Sphere { radius: 0.1 },
        p0.into(),
        v0.into(),
        [0.0; 3],
    ))
    .unwrap();
    world.set_max_substep(0.5);
    let steps = (t_end / 5.0) as usize;
    for _ in 0..steps {
        world.step(5.0);
    }
    let n = world.orbit().mean_motion();
    let (pc, _) = clohessy_wiltshire(n, &p0, &v0, world.time());
    (world.debris()[0].state.p - pc).norm()
}

#[test]
fn nonlinear_relative_motion_converges_to_clohessy_wiltshire() {
    let t = 1500.0;
    let e10 = cw_error(10.0, t) / 10.0;
    let e100 = cw_error(100.0, t) / 100.0;
    // Relative error is small and shrinks linearly with the separation (quadratic nonlinearity).
    // Expected size of the neglected quadratic terms: ~ (ρ/r)·(n t)² ≈ 1e-5 at 10 m, 1500 s.
    assert!(e10 < 3e-5, "relative CW error at 10 m: {e10}");
    let ratio = e10 / e100;
    assert!((0.07..0.14).contains(&ratio), "error ratio {ratio} (expected ≈ 0.1)");
}

fn periodic_orbit_closure(chief_e: f64) {
    let cfg =
        OrbitConfig { eccentricity: chief_e, inclination_deg: 30.0, raan_deg: 20.0, ..Default::default() };
    let orbit = RefOrbit::from_config(&cfg);
    let c0 = orbit.at(0.0);
    // Deputy: same semi-major axis (same period), slightly different e, i, RAAN and phase.
    let (rd, vd) = kepler_to_eci(
        MU_EARTH,
        orbit.a,
        chief_e + 4e-5,
        orbit.inc + 1e-5,
        orbit.raan + 2e-5,
        orbit.argp,
        c0.nu + 3e-5,
    );
    let (p0, v0) = orbit.eci_to_lvlh(0.0, &rd, &vd);
    assert!(p0.norm() > 50.0 && p0.norm() < 2000.0, "initial separation {}", p0.norm());
    let mut world = DebrisWorld::new(&one_body_scene(
        cfg,
        ShapeSpec::Sphere { radius: 0.1 },
        p0.into(),
        v0.into(),
        [0.0; 3],
    ))
    .unwrap();
    world.set_max_substep(0.5);
    let period = orbit.period();
    let steps = 1000;
    let mut max_dev: f64 = 0.0;
    for _ in 0..steps {
        world.step(period / steps as f64);
        max_dev = max_dev.max((world.debris()[0].state.p - p0).norm());
    }
    let s = world.debris()[0].state;
    assert!(max_dev > 100.0, "relative orbit did not move: {max_dev}");
    assert!((s.p - p0).norm() < 1e-3, "position after one period off by {} m", (s.p - p0).norm());
    assert!((s.v - v0).norm() < 1e-6, "velocity after one period off by {} m/s", (s.v - v0).norm());
}

#[test]
fn keplerian_relative_orbit_of_same_period_is_periodic_circular_chief() {
    periodic_orbit_closure(0.0);
}

#[test]
fn keplerian_relative_orbit_of_same_period_is_periodic_elliptic_chief() {
    periodic_orbit_closure(0.02);
}

#[test]
fn differential_j2_is_zero_at_origin_and_small_nearby() {
    let mut cfg = OrbitConfig { inclination_deg: 51.6, ..Default::default() };
    cfg.j2 = true;
    let j2 = RefOrbit::from_config(&cfg);
    cfg.j2 = false;
    let kep = RefOrbit::from_config(&cfg);
    let c = j2.at(1234.0);
    let z = Vector3::zeros();
    assert!(j2.relative_accel(&c, &z, &z).norm() < 1e-15);
    let p = Vector3::new(10.0, -5.0, 3.0);
    let d = (j2.relative_accel(&c, &p, &z) - kep.relative_accel(&c, &p, &z)).norm();
    // Gradient of J2 ~ 3·J2·μ·Re²/r⁵ · |ρ| ≈ 1e-8 m/s² here.
    assert!(d > 1e-10 && d < 1e-6, "differential J2 {d}");
}

#[test]
fn circular_reference_orbit_has_constant_radius_and_rate() {
    let o = RefOrbit::from_config(&OrbitConfig::default());
    let (a, b) = (o.at(0.0), o.at(1000.0));
    assert!((a.r - b.r).abs() < 1e-6 && (a.nu_dot - b.nu_dot).abs() < 1e-15);
    assert!((a.nu_dot - o.mean_motion()).abs() < 1e-15);
    assert!((o.period() - 5553.6).abs() < 1.0, "400 km period {}", o.period());
}

#[test]
fn a_principal_axes_body_steps_as_with_its_full_inertia_matrices() {
    // `attitude_rk4` takes the diagonals of a body in its principal axes; the full products
    // (`euler_rhs`) give the same values, bit for bit, over many steps.
    use dkrrt_debris::body::{attitude_rk4, euler_rhs, quat_rhs, BodyProps};
    use nalgebra::UnitQuaternion;
    let props = BodyProps::new(&ShapeSpec::Box { half_extents: [0.4, 0.15, 0.05] }, 3.0, None).unwrap();
    let diag = |m: &nalgebra::Matrix3<f64>| (0..3).all(|r| (0..3).all(|c| r == c || m[(r, c)] == 0.0));
    assert!(diag(&props.inertia) && diag(&props.inv_inertia));
    let (mut q, mut w) = (UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1), Vector3::new(0.4, -1.3, 0.7));
    let (mut qr, mut wr) = (q, w);
    let (n, h) = ([0.0011, 0.0011, 0.0011], 0.01);
    for _ in 0..2000 {
        attitude_rk4(&props, &mut q, &mut w, n, h);
        // The full-matrix RK4 step.
        let f = |w: &Vector3<f64>| euler_rhs(&props.inertia, &props.inv_inertia, w);
        let (q0, w0) = (*qr.quaternion(), wr);
        let (kq1, kw1) = (quat_rhs(&q0, &w0, n[0]), f(&w0));
        let (q2, w2) = (q0 + kq1 * (0.5 * h), w0 + kw1 * (0.5 * h));
        let (kq2, kw2) = (quat_rhs(&q2, &w2, n[1]), f(&w2));
        let (q3, w3) = (q0 + kq2 * (0.5 * h), w0 + kw2 * (0.5 * h));
        let (kq3, kw3) = (quat_rhs(&q3, &w3, n[1]), f(&w3));
        let (q4, w4) = (q0 + kq3 * h, w0 + kw3 * h);
        let (kq4, kw4) = (quat_rhs(&q4, &w4, n[2]), f(&w4));
        wr = w0 + (kw1 + kw2 * 2.0 + kw3 * 2.0 + kw4) * (h / 6.0);
        qr = UnitQuaternion::new_normalize(q0 + (kq1 + kq2 * 2.0 + kq3 * 2.0 + kq4) * (h / 6.0));
        assert_eq!(w.map(f64::to_bits), wr.map(f64::to_bits));
        assert_eq!(q.coords.map(f64::to_bits), qr.coords.map(f64::to_bits));
    }
}
