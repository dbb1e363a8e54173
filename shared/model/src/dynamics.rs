//! Rigid-body dynamics of the fixed-base arm.
//!
//! Equation of motion (joint space):
//!
//! ```text
//! τ = M(q) q̈ + C(q, q̇) q̇ + g(q)
//! ```
//!
//! * [`ArmModel::rnea`] evaluates the right-hand side (recursive Newton–Euler, body frames),
//! * [`ArmModel::mass_matrix`] is `M(q)` (composite rigid-body algorithm),
//! * [`ArmModel::coriolis_matrix`] is the Christoffel-consistent `C(q, q̇)`
//!   (`Ṁ − 2C` skew-symmetric), computed with the O(N²) algorithm of
//!   Echeandia & Wensing, "Numerical Methods to Compute the Coriolis Matrix and
//!   Christoffel Symbols for Rigid-Body Systems", J. Comput. Nonlinear Dyn. 2021,
//! * [`ArmModel::gravity_torque`] is `g(q)` for the configurable gravity vector
//!   (default zero, i.e. in orbit),
//! * [`ArmModel::forward_dynamics`] solves for `q̈` (CRBA + Cholesky).
//!
//! None of these allocate: all scratch lives in fixed-size stack arrays.

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use crate::model::ArmModel;
use crate::spatial::{crf, crf_bar, force_to_parent, motion_to_child, mul_rz, stack};
use crate::{JMat, JVec, NJ};

impl ArmModel {
    /// Inverse dynamics (recursive Newton–Euler): the joint torques
    /// `τ = M(q) q̈ + C(q, q̇) q̇ + g(q)` that produce acceleration `qdd` at state
    /// (`q`, `qd`) under the model's gravity.
    pub fn rnea(&self, q: &JVec, qd: &JVec, qdd: &JVec) -> JVec {
        self.rnea_posed(&self.joint_rotations(q), qd, qdd)
    }

    /// Each joint's rotation from its parent at `q` (what every pass over the chain starts
    /// from; computed once where two passes share it).
    #[inline]
    fn joint_rotations(&self, q: &JVec) -> [Matrix3<f64>; NJ] {
        std::array::from_fn(|i| mul_rz(&self.rc[i], q[i]))
    }

    /// [`ArmModel::rnea`] with the joint rotations given.
    fn rnea_posed(&self, rot: &[Matrix3<f64>; NJ], qd: &JVec, qdd: &JVec) -> JVec {
        let mut fn_ = [Vector3::zeros(); NJ];
        let mut ff = [Vector3::zeros(); NJ];
        let (mut wp, mut vp) = (Vector3::zeros(), Vector3::zeros());
        // Gravity enters as a fictitious base acceleration −g.
        let (mut awp, mut avp) = (Vector3::zeros(), -self.gravity);
        for i in 0..NJ {
            let r = rot[i];
            let p = &self.pc[i];
            let (mut w, v) = motion_to_child(&r, p, &wp, &vp);
            let (mut aw, mut av) = motion_to_child(&r, p, &awp, &avp);
            let (qdi, qddi) = (qd[i], qdd[i]);
            // a_i = X a_λ + S q̈ + v_i ×ₘ S q̇, with S = (e_z, 0) (ω × e_z = (ω_y, −ω_x, 0)).
            aw += Vector3::new(w.y * qdi, -w.x * qdi, qddi);
            av += Vector3::new(v.y * qdi, -v.x * qdi, 0.0);
            w.z += qdi;
            // f_i = I a_i + v_i ×* I v_i
            let inertia = &self.inertia[i];
            let (ian, iaf) = inertia.mul(&aw, &av);
            let (l, pm) = inertia.mul(&w, &v);
            fn_[i] = ian + w.cross(&l) + v.cross(&pm);
            ff[i] = iaf + w.cross(&pm);
            (wp, vp, awp, avp) = (w, v, aw, av);
        }
        let mut tau = JVec::zeros();
        for i in (0..NJ).rev() {
            tau[i] = fn_[i].z;
            if i > 0 {
                let (n, f) = force_to_parent(&rot[i], &self.pc[i], &fn_[i], &ff[i]);
                fn_[i - 1] += n;
                ff[i - 1] += f;
            }
        }
        tau
    }

    /// Joint-space mass (inertia) matrix `M(q)` (composite rigid-body algorithm).
    /// Symmetric positive definite.
    pub fn mass_matrix(&self, q: &JVec) -> JMat {
        self.mass_matrix_posed(&self.joint_rotations(q))
    }

    /// [`ArmModel::mass_matrix`] with the joint rotations given.
    fn mass_matrix_posed(&self, rot: &[Matrix3<f64>; NJ]) -> JMat {
        let mut ic = self.inertia;
        for i in (1..NJ).rev() {
            let t = ic[i].to_parent(&rot[i], &self.pc[i]);
            ic[i - 1] = ic[i - 1].add(&t);
        }
        let mut m = JMat::zeros();
        for i in 0..NJ {
            // F = I^C_i S_i with S_i = (e_z, 0): (i_o e_z, −h × e_z).
            let mut n = ic[i].i_o.column(2).into_owned();
            let h = ic[i].h;
            let mut f = Vector3::new(-h.y, h.x, 0.0);
            m[(i, i)] = n.z;
            let mut j = i;
            while j > 0 {
                (n, f) = force_to_parent(&rot[j], &self.pc[j], &n, &f);
                j -= 1;
                m[(j, i)] = n.z;
                m[(i, j)] = n.z;
            }
        }
        m
    }

    /// Coriolis/centrifugal matrix `C(q, q̇)` with `C q̇` equal to the velocity
    /// product terms of [`ArmModel::rnea`] and `Ṁ − 2C` skew-symmetric.
    ///
    /// This is the Christoffel-consistent factorisation
    /// `C_ij = Σ_k Γ_ijk q̇_k`, `Γ_ijk = ½(∂M_ij/∂q_k + ∂M_ik/∂q_j − ∂M_jk/∂q_i)`,
    /// computed without differentiating `M` by the algorithm of Echeandia &
    /// Wensing (2021): with world-frame joint motion subspaces `s_j`, their rates
    /// `ṡ_j = v_j ×ₘ s_j`, and per-body
    /// `B_b = ½(v_b ×* I_b − I_b v_b ×ₘ + (I_b v_b) ×̄*)`,
    /// `C_ij = s_iᵀ (I^C_k ṡ_j + B^C_k s_j)` where `k = max(i, j)` and `I^C`, `B^C`
    /// are sums over the subtree.
    pub fn coriolis_matrix(&self, q: &JVec, qd: &JVec) -> JMat {
        let fr = self.body_frames(q);
        let mut s = [Vector6::zeros(); NJ];
        let mut sd = [Vector6::zeros(); NJ];
        let mut ic = [Matrix6::zeros(); NJ];
        let mut bc = [Matrix6::zeros(); NJ];
        let mut v = Vector6::zeros();
        for i in 0..NJ {
            let z = fr.r[i].column(2).into_owned();
            s[i] = stack(&z, &fr.p[i].cross(&z));
            v += s[i] * qd[i];
            // ṡ_i = v_i ×ₘ s_i
            let (vw, vl) = (v.fixed_rows::<3>(0).into_owned(), v.fixed_rows::<3>(3).into_owned());
            let (sw, sl) = (z, s[i].fixed_rows::<3>(3).into_owned());
            sd[i] = stack(&vw.cross(&sw), &(vw.cross(&sl) + vl.cross(&sw)));
            let im = self.inertia[i].to_parent(&fr.r[i], &fr.p[i]).to_matrix();
            // B = ½(crf(v) I − I crm(v) + crf_bar(I v)); I crm(v) = −(crf(v) I)ᵀ.
            let a = crf(&v) * im;
            bc[i] = (a + a.transpose() + crf_bar(&(im * v))) * 0.5;
            ic[i] = im;
        }
        for i in (1..NJ).rev() {
            let (icc, bcc) = (ic[i], bc[i]);
            ic[i - 1] += icc;
            bc[i - 1] += bcc;
        }
        let mut c = JMat::zeros();
        for j in 0..NJ {
            // Entries with i <= j use the composite quantities of body j.
            let f1 = ic[j] * sd[j] + bc[j] * s[j];
            for i in 0..=j {
                c[(i, j)] = s[i].dot(&f1);
            }
            // Entries (j, k) with k < j also use body j's composites.
            let f2 = ic[j] * s[j];
            let f3 = bc[j].tr_mul(&s[j]);
            for k in 0..j {
                c[(j, k)] = f2.dot(&sd[k]) + f3.dot(&s[k]);
            }
        }
        c
    }

    /// Generalised gravity force `g(q) = ∂U/∂q` for the model's gravity vector
    /// (zero by default, in which case this returns zeros).
    pub fn gravity_torque(&self, q: &JVec) -> JVec {
        if self.gravity == Vector3::zeros() {
            return JVec::zeros();
        }
        self.rnea(q, &JVec::zeros(), &JVec::zeros())
    }

    /// Nonlinear effects `C(q, q̇) q̇ + g(q)` (= `rnea(q, q̇, 0)`).
    pub fn nonlinear_effects(&self, q: &JVec, qd: &JVec) -> JVec {
        self.rnea(q, qd, &JVec::zeros())
    }

    /// Forward dynamics: `q̈ = M(q)⁻¹ (τ − C(q, q̇) q̇ − g(q))`, via CRBA and a
    /// Cholesky factorisation.
    pub fn forward_dynamics(&self, q: &JVec, qd: &JVec, tau: &JVec) -> JVec {
        // Both passes start from the same joint rotations.
        let rot = self.joint_rotations(q);
        let m = self.mass_matrix_posed(&rot);
        let rhs = tau - self.rnea_posed(&rot, qd, &JVec::zeros());
        match m.cholesky() {
            Some(ch) => ch.solve(&rhs),
            // Unreachable for a validated model (M is positive definite), kept as
            // a non-panicking fallback for numerically extreme inputs.
            None => m.lu().solve(&rhs).unwrap_or_else(|| JVec::repeat(f64::NAN)),
        }
    }

    /// Kinetic energy `½ q̇ᵀ M(q) q̇` (J).
    pub fn kinetic_energy(&self, q: &JVec, qd: &JVec) -> f64 {
        0.5 * qd.dot(&(self.mass_matrix(q) * qd))
    }

    /// Potential energy `U(q) = −Σ_b m_b g · c_b(q)` (J) in the model's gravity
    /// field (`c_b` = base-frame centre of mass of body `b`).
    pub fn potential_energy(&self, q: &JVec) -> f64 {
        let fr = self.body_frames(q);
        let mut first_moment = Vector3::zeros();
        for i in 0..NJ {
            first_moment += fr.p[i] * self.inertia[i].m + fr.r[i] * self.inertia[i].h;
        }
        -self.gravity.dot(&first_moment)
    }

    /// Base-frame centre of mass of the moving bodies.
    pub fn center_of_mass(&self, q: &JVec) -> Vector3<f64> {
        let fr = self.body_frames(q);
        let mut first_moment = Vector3::zeros();
        let mut mass = 0.0;
        for i in 0..NJ {
            first_moment += fr.p[i] * self.inertia[i].m + fr.r[i] * self.inertia[i].h;
            mass += self.inertia[i].m;
        }
        first_moment / mass
    }
}
