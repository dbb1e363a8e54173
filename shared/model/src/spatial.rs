//! Compact spatial (6-D) algebra written out on 3-vectors.
//!
//! Conventions (Featherstone, "Rigid Body Dynamics Algorithms", 2008):
//!
//! * a motion vector is `(ω, v)`: angular part first, then the linear velocity of
//!   the point that coincides with the frame origin;
//! * a force vector is `(n, f)`: moment about the frame origin first, then force;
//! * a rigid transform between a parent frame `P` and a child frame `C` is stored as
//!   the pose of `C` in `P`: rotation `r` (columns = child axes in parent
//!   coordinates) and translation `p` (child origin in parent coordinates).
//!
//! Everything is fixed-size and lives on the stack; nothing here allocates.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// Skew-symmetric cross-product matrix: `skew(a) * b == a × b`.
#[inline(always)]
pub fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// Rotation about the z axis by `q` applied on the right: returns `r * Rz(q)`.
///
/// Only the first two columns change, so this is 12 flops instead of a 3x3 product.
#[inline(always)]
pub fn mul_rz(r: &Matrix3<f64>, q: f64) -> Matrix3<f64> {
    let (s, c) = q.sin_cos();
    let c0 = r.column(0);
    let c1 = r.column(1);
    let n0 = c0 * c + c1 * s;
    let n1 = c1 * c - c0 * s;
    Matrix3::from_columns(&[n0, n1, r.column(2).into_owned()])
}

/// Spatial inertia of a rigid body, expressed in some body-fixed frame `B`.
///
/// Stored compactly as mass `m`, first moment `h = m c` (`c` = centre of mass in
/// `B`) and the rotational inertia `i_o` about the origin of `B`
/// (`i_o = I_c − m [c]×²`). As a 6x6 matrix it is
/// `[[i_o, [h]×], [[h]×ᵀ, m 1]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpatialInertia {
    /// Mass (kg).
    pub m: f64,
    /// First mass moment `m c` (kg m).
    pub h: Vector3<f64>,
    /// Rotational inertia about the frame origin (kg m²).
    pub i_o: Matrix3<f64>,
}

impl SpatialInertia {
    /// The zero inertia (massless body).
    pub fn zero() -> Self {
        SpatialInertia { m: 0.0, h: Vector3::zeros(), i_o: Matrix3::zeros() }
    }

    /// Build from mass, centre of mass `c` and rotational inertia `i_c` about the
    /// centre of mass, all in frame `B`.
    pub fn from_com(m: f64, c: &Vector3<f64>, i_c: &Matrix3<f64>) -> Self {
        let cx = skew(c);
        SpatialInertia { m, h: c * m, i_o: i_c - cx * cx * m }
    }

    /// Momentum `I v` of the motion `v = (ω, vl)`; returns `(angular, linear)`.
    #[inline(always)]
    pub fn mul(&self, w: &Vector3<f64>, v: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        (self.i_o * w + self.h.cross(v), v * self.m - self.h.cross(w))
    }

    /// Express an inertia given in a child frame `C` in its parent frame `P`,
    /// where `(r, p)` is the pose of `C` in `P` (i.e. `Xᵀ I X`).
    #[inline(always)]
    pub fn to_parent(&self, r: &Matrix3<f64>, p: &Vector3<f64>) -> SpatialInertia {
        let hr = r * self.h;
        // R i_o Rᵀ, computing only the 6 unique entries of the symmetric result.
        let a = r * self.i_o;
        let d = |i: usize, j: usize| a[(i, 0)] * r[(j, 0)] + a[(i, 1)] * r[(j, 1)] + a[(i, 2)] * r[(j, 2)];
        let (xx, yy, zz, xy, xz, yz) = (d(0, 0), d(1, 1), d(2, 2), d(0, 1), d(0, 2), d(1, 2));
        // i_p = R i_o Rᵀ − m [p]×² − [p]×[Rh]× − [Rh]×[p]×, using [a]×[b]× = b aᵀ − (a·b) 1:
        //     = R i_o Rᵀ − m (p pᵀ − |p|² 1) − (h pᵀ + p hᵀ) + 2 (p·h) 1   (h = R h_c)
        let m = self.m;
        let diag = m * p.norm_squared() + 2.0 * p.dot(&hr);
        let e = |i: usize, j: usize| -m * p[i] * p[j] - hr[i] * p[j] - p[i] * hr[j];
        let (exy, exz, eyz) = (xy + e(0, 1), xz + e(0, 2), yz + e(1, 2));
        let i_p = Matrix3::new(
            xx + e(0, 0) + diag,
            exy,
            exz,
            exy,
            yy + e(1, 1) + diag,
            eyz,
            exz,
            eyz,
            zz + e(2, 2) + diag,
        );
        SpatialInertia { m, h: hr + p * m, i_o: i_p }
    }

    /// Sum of two inertias expressed in the same frame.
    #[inline(always)]
    pub fn add(&self, o: &SpatialInertia) -> SpatialInertia {
        SpatialInertia { m: self.m + o.m, h: self.h + o.h, i_o: self.i_o + o.i_o }
    }

    /// The full 6x6 matrix `[[i_o, [h]×], [[h]×ᵀ, m 1]]`.
    pub fn to_matrix(&self) -> Matrix6<f64> {
        let hx = skew(&self.h);
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.i_o);
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&hx);
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&hx.transpose());
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&(Matrix3::identity() * self.m));
        out
    }
}

/// Transform a motion vector `(w, v)` given in parent coordinates into child
/// coordinates, where `(r, p)` is the pose of the child in the parent.
#[inline(always)]
pub fn motion_to_child(
    r: &Matrix3<f64>,
    p: &Vector3<f64>,
    w: &Vector3<f64>,
    v: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    (r.tr_mul(w), r.tr_mul(&(v + w.cross(p))))
}

/// Transform a force `(n, f)` given in child coordinates into parent
/// coordinates, where `(r, p)` is the pose of the child in the parent.
#[inline(always)]
pub fn force_to_parent(
    r: &Matrix3<f64>,
    p: &Vector3<f64>,
    n: &Vector3<f64>,
    f: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let fp = r * f;
    (r * n + p.cross(&fp), fp)
}

/// Stack angular and linear parts into a 6-vector `(a, l)`.
#[inline(always)]
pub fn stack(a: &Vector3<f64>, l: &Vector3<f64>) -> Vector6<f64> {
    Vector6::new(a.x, a.y, a.z, l.x, l.y, l.z)
}

/// Motion cross-product matrix `crm(v)`: `crm(v) * m == v ×ₘ m`.
pub fn crm(v: &Vector6<f64>) -> Matrix6<f64> {
    let wx = skew(&v.fixed_rows::<3>(0).into_owned());
    let vx = skew(&v.fixed_rows::<3>(3).into_owned());
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&wx);
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&vx);
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&wx);
    out
}

/// Force cross-product matrix `crf(v) = −crm(v)ᵀ`: `crf(v) * f == v ×* f`.
pub fn crf(v: &Vector6<f64>) -> Matrix6<f64> {
    -crm(v).transpose()
}

/// The "bar" force cross-product matrix: `crf_bar(f) * v == v ×* f`.
///
/// It is skew-symmetric, which is what makes the Coriolis matrix of
/// [`crate::ArmModel::coriolis_matrix`] satisfy the `Ṁ − 2C` skew property.
pub fn crf_bar(f: &Vector6<f64>) -> Matrix6<f64> {
    let nx = skew(&f.fixed_rows::<3>(0).into_owned());
    let fx = skew(&f.fixed_rows::<3>(3).into_owned());
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-nx));
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-fx));
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-fx));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v3(a: f64, b: f64, c: f64) -> Vector3<f64> {
        Vector3::new(a, b, c)
    }

    fn rot(rpy: [f64; 3]) -> Matrix3<f64> {
        *nalgebra::Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]).matrix()
    }

    #[test]
    fn mul_rz_matches_rotation_product() {
        let r = rot([0.3, -0.7, 1.9]);
        let q = 0.83;
        let rz = *nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), q).matrix();
        assert!((mul_rz(&r, q) - r * rz).norm() < 1e-14);
    }

    #[test]
    fn inertia_mul_matches_matrix() {
        let i = SpatialInertia::from_com(
            3.0,
            &v3(0.1, -0.2, 0.3),
            &Matrix3::new(0.5, 0.01, 0.02, 0.01, 0.4, 0.03, 0.02, 0.03, 0.3),
        );
        let (w, v) = (v3(0.3, 0.2, -0.5), v3(1.0, -2.0, 0.7));
        let (a, l) = i.mul(&w, &v);
        let full = i.to_matrix() * stack(&w, &v);
        assert!((stack(&a, &l) - full).norm() < 1e-13);
    }

    #[test]
    fn inertia_transform_matches_6x6_congruence() {
        let i = SpatialInertia::from_com(
            2.0,
            &v3(0.4, 0.1, -0.3),
            &Matrix3::new(0.2, 0.0, 0.01, 0.0, 0.3, 0.0, 0.01, 0.0, 0.25),
        );
        let r = rot([0.5, 0.2, -1.1]);
        let p = v3(0.3, -0.6, 1.2);
        // Build the 6x6 motion transform parent -> child: X = [[Rᵀ, 0], [−Rᵀ[p]×, Rᵀ]].
        let rt = r.transpose();
        let mut x = Matrix6::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
        x.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-rt * skew(&p)));
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&rt);
        let expect = x.transpose() * i.to_matrix() * x;
        assert!((i.to_parent(&r, &p).to_matrix() - expect).norm() < 1e-12);
        // And the motion/force helpers agree with X.
        let (w, v) = (v3(0.1, 0.2, 0.3), v3(-0.4, 0.5, 0.6));
        let (wc, vc) = motion_to_child(&r, &p, &w, &v);
        assert!((stack(&wc, &vc) - x * stack(&w, &v)).norm() < 1e-13);
        let (n, f) = force_to_parent(&r, &p, &w, &v);
        assert!((stack(&n, &f) - x.transpose() * stack(&w, &v)).norm() < 1e-13);
    }

    #[test]
    fn cross_operators_are_consistent() {
        let v = Vector6::new(0.1, -0.3, 0.2, 1.0, 0.5, -0.7);
        let u = Vector6::new(-0.2, 0.4, 0.9, 0.3, -0.1, 0.8);
        let f = Vector6::new(0.6, 0.2, -0.4, -1.0, 0.3, 0.2);
        assert!((crf(&v) * f - crf_bar(&f) * v).norm() < 1e-14);
        // Skew symmetry of crf_bar.
        let b = crf_bar(&f);
        assert!((b + b.transpose()).norm() < 1e-14);
        // Duality: (v ×ₘ u)·f = −u·(v ×* f).
        let lhs = (crm(&v) * u).dot(&f);
        let rhs = -(u.dot(&(crf(&v) * f)));
        assert!((lhs - rhs).abs() < 1e-14);
    }
}
