//! Shared helpers for the integration tests: seeded random states and a random
//! (but valid) URDF generator exercising arbitrary origins, rpy, axes and fixed joints.
#![allow(dead_code)]

use dkrrt_model::{ArmModel, JVec, NJ};
use nalgebra::{Isometry3, Matrix3, Rotation3, Vector3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

pub fn rng(seed: u64) -> SmallRng {
    SmallRng::seed_from_u64(seed)
}

/// Uniform configuration within the joint limits (continuous joints: [-π, π]).
pub fn random_q(m: &ArmModel, r: &mut SmallRng) -> JVec {
    let l = m.limits();
    JVec::from_fn(|i, _| {
        let (lo, hi) = if l.q_min[i].is_finite() {
            (l.q_min[i], l.q_max[i])
        } else {
            (-std::f64::consts::PI, std::f64::consts::PI)
        };
        r.random_range(lo..hi)
    })
}

/// Uniform vector with entries in [-s, s].
pub fn random_vec(r: &mut SmallRng, s: f64) -> JVec {
    JVec::from_fn(|_, _| r.random_range(-s..s))
}

/// Relative error |a − b| / (1 + |b|) for any nalgebra matrix.
pub fn rel<const R: usize, const C: usize>(
    a: &nalgebra::SMatrix<f64, R, C>,
    b: &nalgebra::SMatrix<f64, R, C>,
) -> f64 {
    (a - b).norm() / (1.0 + b.norm())
}

/// Angular velocity `ω` with `R(q + ε) ≈ exp(ε ω) R(q)`, from two poses 2ε apart.
pub fn rot_rate(plus: &Isometry3<f64>, minus: &Isometry3<f64>, two_eps: f64) -> Vector3<f64> {
    (plus.rotation * minus.rotation.inverse()).scaled_axis() / two_eps
}

fn f(r: &mut SmallRng, lo: f64, hi: f64) -> f64 {
    r.random_range(lo..hi)
}

fn v3s(v: [f64; 3]) -> String {
    format!("{:.17} {:.17} {:.17}", v[0], v[1], v[2])
}

/// A random valid `<inertial>` block (rotated principal frame, off-diagonal terms).
fn inertial(r: &mut SmallRng) -> String {
    let m = f(r, 0.5, 20.0);
    // Principal moments satisfying the triangle inequality: from a random
    // non-negative second-moment distribution (a, b, c): I = (b+c, a+c, a+b).
    let (a, b, c) = (f(r, 0.01, 0.5), f(r, 0.01, 0.5), f(r, 0.01, 0.5));
    let d = Matrix3::from_diagonal(&Vector3::new(b + c, a + c, a + b));
    let rot = Rotation3::from_euler_angles(f(r, -3.0, 3.0), f(r, -1.5, 1.5), f(r, -3.0, 3.0));
    let i = rot.matrix() * d * rot.matrix().transpose();
    format!(
        r#"<inertial><origin xyz="{}" rpy="{}"/><mass value="{m:.17}"/>
           <inertia ixx="{:.17}" ixy="{:.17}" ixz="{:.17}" iyy="{:.17}" iyz="{:.17}" izz="{:.17}"/></inertial>"#,
        v3s([f(r, -0.3, 0.3), f(r, -0.3, 0.3), f(r, -0.3, 0.3)]),
        // The tensor is given in the inertial frame: exercise that rotation too.
        v3s([f(r, -3.0, 3.0), f(r, -1.5, 1.5), f(r, -3.0, 3.0)]),
        i[(0, 0)],
        i[(0, 1)],
        i[(0, 2)],
        i[(1, 1)],
        i[(1, 2)],
        i[(2, 2)]
    )
}

fn collision(r: &mut SmallRng) -> String {
    format!(
        r#"<collision><origin xyz="{}" rpy="{}"/><geometry><cylinder radius="{:.5}" length="{:.5}"/></geometry></collision>"#,
        v3s([f(r, -0.2, 0.2), f(r, -0.2, 0.2), f(r, -0.2, 0.2)]),
        v3s([f(r, -3.0, 3.0), f(r, -1.5, 1.5), f(r, -3.0, 3.0)]),
        f(r, 0.03, 0.15),
        f(r, 0.1, 0.6)
    )
}

/// A random serial 6-DoF URDF with: a fixed joint before the first actuated
/// joint, random joint origins (xyz + rpy), random axes (one exactly −z, one
/// continuous joint), a massive fixed link between actuated joints 3 and 4, and
/// a fixed massive end effector plus a massless tool frame at the tip.
pub fn random_urdf(seed: u64) -> String {
    let mut r = rng(seed);
    let mut s = String::from("<robot name=\"random_arm\">\n<link name=\"world\"/>\n");
    s += &format!("<link name=\"base\">{}</link>\n", inertial(&mut r));
    s += &format!(
        "<joint name=\"mount\" type=\"fixed\"><origin xyz=\"{}\" rpy=\"{}\"/><parent link=\"world\"/><child link=\"base\"/></joint>\n",
        v3s([f(&mut r, -0.5, 0.5), f(&mut r, -0.5, 0.5), f(&mut r, -0.5, 0.5)]),
        v3s([f(&mut r, -3.0, 3.0), f(&mut r, -1.5, 1.5), f(&mut r, -3.0, 3.0)])
    );
    let mut parent = "base".to_string();
    for k in 0..NJ {
        let child = format!("l{k}");
        let axis = if k == 2 {
            [0.0, 0.0, -1.0]
        } else {
            [f(&mut r, -1.0, 1.0), f(&mut r, -1.0, 1.0), f(&mut r, -1.0, 1.0)]
        };
        let kind = if k == 4 { "continuous" } else { "revolute" };
        s += &format!(
            "<joint name=\"j{k}\" type=\"{kind}\"><origin xyz=\"{}\" rpy=\"{}\"/><parent link=\"{parent}\"/><child link=\"{child}\"/><axis xyz=\"{}\"/><limit lower=\"-2.5\" upper=\"2.7\" velocity=\"1.5\" effort=\"100\"/></joint>\n",
            v3s([f(&mut r, -0.5, 0.5), f(&mut r, -0.5, 0.5), f(&mut r, -0.5, 0.5)]),
            v3s([f(&mut r, -3.0, 3.0), f(&mut r, -1.5, 1.5), f(&mut r, -3.0, 3.0)]),
            v3s(axis)
        );
        s += &format!("<link name=\"{child}\">{}{}</link>\n", inertial(&mut r), collision(&mut r));
        parent = child;
        if k == 2 {
            s += &format!("<link name=\"l2_fixed\">{}</link>\n", inertial(&mut r));
            s += &format!(
                "<joint name=\"l2_fix\" type=\"fixed\"><origin xyz=\"{}\" rpy=\"{}\"/><parent link=\"l2\"/><child link=\"l2_fixed\"/></joint>\n",
                v3s([f(&mut r, -0.5, 0.5), f(&mut r, -0.5, 0.5), f(&mut r, -0.5, 0.5)]),
                v3s([f(&mut r, -3.0, 3.0), f(&mut r, -1.5, 1.5), f(&mut r, -3.0, 3.0)])
            );
            parent = "l2_fixed".to_string();
        }
    }
    s += &format!("<link name=\"ee\">{}</link>\n", inertial(&mut r));
    s += &format!(
        "<joint name=\"ee_fix\" type=\"fixed\"><origin xyz=\"{}\" rpy=\"{}\"/><parent link=\"{parent}\"/><child link=\"ee\"/></joint>\n",
        v3s([f(&mut r, -0.3, 0.3), f(&mut r, -0.3, 0.3), f(&mut r, -0.3, 0.3)]),
        v3s([f(&mut r, -3.0, 3.0), f(&mut r, -1.5, 1.5), f(&mut r, -3.0, 3.0)])
    );
    s += "<link name=\"tool\"/>\n";
    s += &format!(
        "<joint name=\"tool_fix\" type=\"fixed\"><origin xyz=\"{}\" rpy=\"{}\"/><parent link=\"ee\"/><child link=\"tool\"/></joint>\n",
        v3s([f(&mut r, -0.3, 0.3), f(&mut r, -0.3, 0.3), f(&mut r, -0.3, 0.3)]),
        v3s([f(&mut r, -3.0, 3.0), f(&mut r, -1.5, 1.5), f(&mut r, -3.0, 3.0)])
    );
    s += "</robot>\n";
    s
}

/// The shipped arm and a few random arms, all with the given gravity.
pub fn models(gravity: Vector3<f64>) -> Vec<(String, ArmModel)> {
    let mut out = vec![("default".to_string(), ArmModel::default_arm())];
    for seed in [11u64, 12, 13] {
        let m = ArmModel::from_urdf_str(&random_urdf(seed)).expect("random URDF is valid");
        out.push((format!("random{seed}"), m));
    }
    for (_, m) in &mut out {
        m.set_gravity(gravity);
    }
    out
}
