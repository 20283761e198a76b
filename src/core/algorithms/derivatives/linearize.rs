//! The dynamics linearised about one point `(q, q̇, τ)`, for the state `x = [q; q̇]` with `q` on
//! the tangent of [the module](super) (`q ⊕ δq`, a floating base perturbed in its own body
//! frame) and the input `u = τ`, both in `v` order. Rows and columns of `A` are `[δq; δq̇]`.
//!
//! **Continuous time** (`dt = 0`), `δẋ = A δx + B δu`:
//!
//! ```text
//! A = [−ad(q̇)  1; ∂q̈/∂q  ∂q̈/∂q̇],   B = [0; H⁻¹]
//! ```
//!
//! `ad(q̇)` is zero but for a floating base, where it is the twist's own cross product
//! `ad(ν) = [ω×  v×; 0  ω×]` (`ν = [v; ω]`): a base perturbation `M exp(δq)` carried along
//! the nominal motion `Ṁ = M ν` changes as `δq̇ = −ad(ν) δq + δν`. With the base at rest (or a
//! fixed base) `A` is the textbook `[0 1; ∂q̈/∂q ∂q̈/∂q̇]`.
//!
//! **Discrete time** (`dt = h > 0`): the exact first-order map `δx⁺ = A δx + B δu` of one step of
//! the simulator's semi-implicit Euler scheme with `τ` held over the step,
//! `q̇⁺ = q̇ + h q̈(q, q̇, τ)`, `q⁺ = q ⊕ h q̇⁺` ([`Model::integrate`]), `δq⁺` measured on the
//! tangent at `q⁺`. With `D_q`, `D_v` the Jacobians of `⊕` at `(q, h q̇⁺)`
//! ([`integrate_jacobians`]; identity but for a floating base):
//!
//! ```text
//! δq̇⁺ = h ∂q̈/∂q δq + (1 + h ∂q̈/∂q̇) δq̇ + h H⁻¹ δτ
//! δq⁺ = D_q δq + h D_v δq̇⁺
//! A = [D_q + h² D_v ∂q̈/∂q   h D_v (1 + h ∂q̈/∂q̇);  h ∂q̈/∂q   1 + h ∂q̈/∂q̇],
//! B = [h² D_v H⁻¹;  h H⁻¹]
//! ```
//!
//! `A = 1 + h A_c + O(h²)` with `A_c` the continuous `A`. No contacts or external wrenches
//! enter. [`linearize`] is of the model's own dynamics under `τ`, the simulator's step with its
//! passive forces off.
//!
//! **Passive joint forces** ([`linearize_with_passive`]): the simulator's dynamics
//! `q̈ = FD(q, q̇, τ_t)` under the total effort `τ_t = clamp(τ) + τ_p(q, q̇)`
//! ([`PassiveForces::total`]), evaluated at the step's start `(q, q̇)` as semi-implicit Euler
//! does. Every passive term acts on one one-dof coordinate alone, so its partials are diagonal
//! ([`PassiveForces::total_partials`]): with `P_q = diag(∂τ_p/∂q)`, `P_v = diag(∂τ_p/∂q̇)`,
//! `U = diag(clamp'(τ))` (0 for a clamped command, else 1) and the derivatives of `FD` taken
//! at `τ_t`,
//!
//! ```text
//! ∂q̈/∂q = ∂FD/∂q + H⁻¹ P_q,   ∂q̈/∂q̇ = ∂FD/∂q̇ + H⁻¹ P_v,   ∂q̈/∂τ = H⁻¹ U
//! ```
//!
//! and these take the place of `∂q̈/∂q`, `∂q̈/∂q̇` and `H⁻¹` in `A` and `B` above (`B`'s
//! column `j` is scaled by `U_jj`).

use super::integrate_jacobians::integrate_jacobians;
use super::rnea_derivatives::check_matrix;
use super::{aba_derivatives, AbaDerivatives};
use crate::error::{check_len, DynamicsError};
use crate::model::{JointKind, Model};
use crate::sim::{Passive, PassiveForces};
use crate::spatial::{skew, Vector3};
use crate::{Externals, Workspace};
use nalgebra::DMatrix;

/// `A` (`2nv × 2nv`) and `B` (`2nv × nv`) of [`linearize`], with its scratch; made once per
/// model by [`Linearization::new`].
#[derive(Clone, Debug)]
pub struct Linearization {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    dq: DMatrix<f64>,
    dv: DMatrix<f64>,
    v_next: Vec<f64>,
    /// The total effort `τ_t` and the diagonals `∂τ_t/∂q`, `∂τ_t/∂q̇`, `∂τ_t/∂τ` of the
    /// passive forces.
    tau_total: Vec<f64>,
    dtau_dq: Vec<f64>,
    dtau_dv: Vec<f64>,
    dtau_du: Vec<f64>,
}

impl Linearization {
    /// Zeroed matrices sized for `model`.
    pub fn new(model: &Model) -> Self {
        let nv = model.nv();
        // From zeroed allocations, as the workspace's matrices: untouched pages cost nothing.
        let zeros =
            |rows: usize, cols: usize| DMatrix::from_vec(rows, cols, vec![0.0; rows * cols]);
        Linearization {
            a: zeros(2 * nv, 2 * nv),
            b: zeros(2 * nv, nv),
            dq: zeros(nv, nv),
            dv: zeros(nv, nv),
            v_next: vec![0.0; nv],
            tau_total: vec![0.0; nv],
            dtau_dq: vec![0.0; nv],
            dtau_dv: vec![0.0; nv],
            dtau_du: vec![0.0; nv],
        }
    }

    /// `A`: rows and columns `[δq; δq̇]`, each in `v` order.
    pub fn a(&self) -> &DMatrix<f64> {
        &self.a
    }

    /// `B`: rows `[δq; δq̇]`, columns `δτ`, in `v` order.
    pub fn b(&self) -> &DMatrix<f64> {
        &self.b
    }
}

/// Linearises `q̈ = FD(q, q̇, τ)` at one point into `out`: continuous time for `dt = 0`, one
/// semi-implicit Euler step of `dt` for `dt > 0` (the module doc gives both). Returns the
/// derivatives of forward dynamics it is made of; `q̈` is left in `ws.qdd()`. A negative or
/// non-finite `dt` is [`DynamicsError::BadStep`]; `out` made for a model of another size, a
/// [`DynamicsError::Length`]. Allocates nothing.
pub fn linearize<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
    out: &mut Linearization,
) -> Result<AbaDerivatives<'w>, DynamicsError> {
    linearize_with_passive(model, ws, q, v, tau, dt, None, out)
}

/// [`linearize`] of the simulator's dynamics with the passive joint forces `passive` (the
/// forces' joint data and which of them act) added to the command `τ`:
/// `q̈ = FD(q, q̇, clamp(τ) + τ_p(q, q̇))` (the module doc gives the partials). `None` is
/// [`linearize`]. The returned `∂q̈/∂q`, `∂q̈/∂q̇` include the passive terms; its `minv` is
/// `H⁻¹ = ∂q̈/∂τ_t`, of the total effort (`B` carries `clamp'`); `q̈` is left in `ws.qdd()`.
/// Allocates nothing.
#[allow(clippy::too_many_arguments)]
pub fn linearize_with_passive<'w>(
    model: &Model,
    ws: &'w mut Workspace,
    q: &[f64],
    v: &[f64],
    tau: &[f64],
    dt: f64,
    passive: Option<(&PassiveForces, &Passive)>,
    out: &mut Linearization,
) -> Result<AbaDerivatives<'w>, DynamicsError> {
    if !(dt.is_finite() && dt >= 0.0) {
        return Err(DynamicsError::BadStep { dt });
    }
    let nv = model.nv();
    check_len(
        "the Linearization (made for a model of another size)",
        nv,
        out.v_next.len(),
    )?;
    let tau = match passive {
        Some((forces, on)) => {
            check_len("q", model.nq(), q.len())?;
            check_len("v", nv, v.len())?;
            check_len("tau", nv, tau.len())?;
            forces.total(on, q, v, tau, &mut out.tau_total);
            forces.total_partials(
                on,
                q,
                v,
                tau,
                &mut out.dtau_dq,
                &mut out.dtau_dv,
                &mut out.dtau_du,
            );
            &out.tau_total[..]
        }
        None => {
            out.dtau_dq.fill(0.0);
            out.dtau_dv.fill(0.0);
            out.dtau_du.fill(1.0);
            tau
        }
    };
    aba_derivatives(model, ws, q, v, tau, &Externals::none())?;
    add_passive_partials(ws, &out.dtau_dq, &out.dtau_dv);
    let d = &ws.derivatives;
    let (a, b) = (&mut out.a, &mut out.b);
    if dt == 0.0 {
        a.fill(0.0);
        b.fill(0.0);
        a.view_mut((0, nv), (nv, nv)).fill_with_identity();
        for j in model.coordinate_joints() {
            if let JointKind::Floating = j.kind {
                let s = j.v_index;
                let lin = Vector3::new(v[s], v[s + 1], v[s + 2]);
                let ang = Vector3::new(v[s + 3], v[s + 4], v[s + 5]);
                a.fixed_view_mut::<3, 3>(s, s).copy_from(&-skew(&ang));
                a.fixed_view_mut::<3, 3>(s, s + 3).copy_from(&-skew(&lin));
                a.fixed_view_mut::<3, 3>(s + 3, s + 3)
                    .copy_from(&-skew(&ang));
            }
        }
        a.view_mut((nv, 0), (nv, nv)).copy_from(&d.ddq_dq);
        a.view_mut((nv, nv), (nv, nv)).copy_from(&d.ddq_dv);
        b.view_mut((nv, 0), (nv, nv)).copy_from(&d.minv);
    } else {
        let h = dt;
        for ((next, v), qdd) in out.v_next.iter_mut().zip(v).zip(ws.qdd.iter()) {
            *next = v + h * qdd;
        }
        integrate_jacobians(model, q, &out.v_next, h, &mut out.dq, &mut out.dv)?;
        // The velocity rows: δq̇⁺ = h ∂q̈/∂q δq + (1 + h ∂q̈/∂q̇) δq̇ + h H⁻¹ δτ.
        let mut rows = a.view_mut((nv, 0), (nv, nv));
        rows.copy_from(&d.ddq_dq);
        rows *= h;
        let mut rows = a.view_mut((nv, nv), (nv, nv));
        rows.copy_from(&d.ddq_dv);
        rows *= h;
        for i in 0..nv {
            rows[(i, i)] += 1.0;
        }
        let mut rows = b.view_mut((nv, 0), (nv, nv));
        rows.copy_from(&d.minv);
        rows *= h;
        // The position rows: h D_v times the velocity rows, plus D_q on δq. Column by column
        // (a matrix-vector product each: no packing buffers).
        for m in [&mut *a, &mut *b] {
            let (mut top, bottom) = m.rows_range_pair_mut(0..nv, nv..2 * nv);
            for c in 0..top.ncols() {
                top.column_mut(c).gemv(h, &out.dv, &bottom.column(c), 0.0);
            }
        }
        let mut top_left = a.view_mut((0, 0), (nv, nv));
        top_left += &out.dq;
    }
    for (mut column, &u) in b.column_iter_mut().zip(&out.dtau_du) {
        if u != 1.0 {
            column *= u;
        }
    }
    check_matrix(model, "A", a)?;
    check_matrix(model, "B", b)?;
    Ok(AbaDerivatives {
        ddq_dq: &ws.derivatives.ddq_dq,
        ddq_dv: &ws.derivatives.ddq_dv,
        minv: &ws.derivatives.minv,
    })
}

/// `∂q̈/∂q += H⁻¹ diag(p_q)`, `∂q̈/∂q̇ += H⁻¹ diag(p_v)` in `ws`'s derivatives of forward
/// dynamics: column `j` of `H⁻¹` scaled by the passive partial of coordinate `j`.
fn add_passive_partials(ws: &mut Workspace, p_q: &[f64], p_v: &[f64]) {
    let d = &mut ws.derivatives;
    for (j, (&pq, &pv)) in p_q.iter().zip(p_v).enumerate() {
        if pq != 0.0 {
            d.ddq_dq.column_mut(j).axpy(pq, &d.minv.column(j), 1.0);
        }
        if pv != 0.0 {
            d.ddq_dv.column_mut(j).axpy(pv, &d.minv.column(j), 1.0);
        }
    }
}
