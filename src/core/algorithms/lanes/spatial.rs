//! The lane forms of the spatial quantities and actions RNEA uses ([`crate::spatial`]'s, one
//! state per lane): motions and forces, the rigid-body inertia's `I v`, the two cross products
//! and the three forms a joint transform `ⁱX_λ` acts in. Each computes the scalar form's
//! operations in the scalar form's order (cited at each), so that every lane has its bits.

use super::value::{mul, splat_matrix, tr_mul, Lanes, M3, V3};
use crate::spatial::{Inertia, Motion, Transform};

/// A spatial motion vector `[ω; v]` of each lane's state (as [`Motion`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct LaneMotion {
    pub(crate) ang: V3,
    pub(crate) lin: V3,
}

/// A spatial force vector `[n; f]` of each lane's state (as [`Force`](crate::spatial::Force)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct LaneForce {
    pub(crate) ang: V3,
    pub(crate) lin: V3,
}

impl crate::algorithms::rnea::AlongAxis for LaneMotion {
    type Scalar = Lanes;
    #[inline(always)]
    fn add_along(&mut self, j: usize, x: Lanes) {
        LaneMotion::add_along(self, j, x)
    }
    #[inline(always)]
    fn add_cross_axis(&mut self, m: &LaneMotion, j: usize, w: Lanes) {
        LaneMotion::add_cross_axis(self, m, j, w)
    }
}

impl LaneMotion {
    /// A motion constant across lanes.
    pub(crate) fn splat(m: &Motion) -> Self {
        LaneMotion {
            ang: V3::splat(&m.ang),
            lin: V3::splat(&m.lin),
        }
    }

    /// Every component times `s` (`Motion * f64`).
    #[inline(always)]
    pub(crate) fn scale(&self, s: Lanes) -> LaneMotion {
        LaneMotion {
            ang: self.ang.scale(s),
            lin: self.lin.scale(s),
        }
    }

    /// `[ω; v] ×̂ [m_ω; m_v] = [ω × m_ω; ω × m_v + v × m_ω]` ([`Motion::cross_motion`]).
    #[inline(always)]
    pub(crate) fn cross_motion(&self, m: &LaneMotion) -> LaneMotion {
        LaneMotion {
            ang: self.ang.cross(&m.ang),
            lin: self.ang.cross(&m.lin) + self.lin.cross(&m.ang),
        }
    }

    /// `mᵀ f = ω·n + v·f` ([`Motion::dot`]), each dot `(a₀ b₀ + a₁ b₁) + a₂ b₂`.
    #[inline(always)]
    pub(crate) fn dot(&self, f: &LaneForce) -> Lanes {
        self.ang.dot(&f.ang) + self.lin.dot(&f.lin)
    }

    /// `x` added to component `j` of `[ω; v]` ([`Motion::add_along`]).
    #[inline(always)]
    pub(crate) fn add_along(&mut self, j: usize, x: Lanes) {
        if j < 3 {
            self.ang[j] += x;
        } else {
            self.lin[j - 3] += x;
        }
    }

    /// `self += w (m ×̂ e_j)`, its nonzero components only ([`Motion::add_cross_axis`]).
    #[inline(always)]
    pub(crate) fn add_cross_axis(&mut self, m: &LaneMotion, j: usize, w: Lanes) {
        if j < 3 {
            add_cross_unit(&mut self.ang, &m.ang, j, w);
            add_cross_unit(&mut self.lin, &m.lin, j, w);
        } else {
            add_cross_unit(&mut self.lin, &m.ang, j - 3, w);
        }
    }

    /// `v ×* f = [ω × n + v × f; ω × f]` ([`Motion::cross_force`]).
    #[inline(always)]
    pub(crate) fn cross_force(&self, f: &LaneForce) -> LaneForce {
        LaneForce {
            ang: self.ang.cross(&f.ang) + self.lin.cross(&f.lin),
            lin: self.ang.cross(&f.lin),
        }
    }
}

/// `out += w (x × e_k)`: `out_i += x_j w`, `out_j −= x_i w` with `(i, j) = (k + 1, k + 2)` mod 3
/// (`add_cross_unit` of [`Motion::add_cross_axis`]).
#[inline(always)]
fn add_cross_unit(out: &mut V3, x: &V3, k: usize, w: Lanes) {
    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
    out[i] += x[j] * w;
    out[j] -= x[i] * w;
}

impl std::ops::Add for LaneMotion {
    type Output = LaneMotion;
    #[inline(always)]
    fn add(self, o: LaneMotion) -> LaneMotion {
        LaneMotion {
            ang: self.ang + o.ang,
            lin: self.lin + o.lin,
        }
    }
}

impl LaneForce {
    /// Component `j` of `[n; f]`.
    #[inline(always)]
    pub(crate) fn component(&self, j: usize) -> Lanes {
        if j < 3 {
            self.ang[j]
        } else {
            self.lin[j - 3]
        }
    }
}

impl std::ops::Add for LaneForce {
    type Output = LaneForce;
    #[inline(always)]
    fn add(self, o: LaneForce) -> LaneForce {
        LaneForce {
            ang: self.ang + o.ang,
            lin: self.lin + o.lin,
        }
    }
}

impl std::ops::AddAssign for LaneForce {
    #[inline(always)]
    fn add_assign(&mut self, o: LaneForce) {
        self.ang += o.ang;
        self.lin += o.lin;
    }
}

/// A body's rigid-body inertia `(m, h, Ī)` in every lane (the model's, the same for every
/// state), `Ī` by rows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct LaneInertia {
    mass: Lanes,
    h: V3,
    i_bar: M3,
}

impl LaneInertia {
    pub(crate) fn splat(inertia: &Inertia) -> Self {
        LaneInertia {
            mass: Lanes::splat(inertia.mass),
            h: V3::splat(&inertia.h),
            i_bar: splat_matrix(&inertia.i_bar),
        }
    }

    /// `I v = [Ī ω + h × v; m v − h × ω]` ([`Inertia::apply`]).
    #[inline(always)]
    pub(crate) fn apply(&self, v: &LaneMotion) -> LaneForce {
        LaneForce {
            ang: mul(&self.i_bar, &v.ang) + self.h.cross(&v.lin),
            lin: v.lin.scale(self.mass) - self.h.cross(&v.ang),
        }
    }
}

/// `ⁱX_λ = rot(E) xlt(r)` of each lane's state, `E` by rows (as [`Transform`]). A joint whose
/// transform acts in a cheaper form ([`UpShape`](crate::model::UpShape)) fills only what that
/// form reads ([`with_lane_transform`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct LaneTransform {
    pub(crate) rot: M3,
    pub(crate) trans: V3,
}

impl LaneTransform {
    /// A model constant (a joint placement `X_tree`).
    pub(crate) fn splat(x: &Transform) -> Self {
        LaneTransform {
            rot: splat_matrix(&x.rot),
            trans: V3::splat(&x.trans),
        }
    }
}

/// The actions of `ⁱX_λ` the passes use, for each form it acts in (as
/// [`SpatialTransform`](crate::spatial::SpatialTransform)).
pub(crate) trait LaneSpatialTransform {
    /// `X m`, a motion from parent into body coordinates.
    fn apply_motion(&self, m: &LaneMotion) -> LaneMotion;
    /// `Xᵀ f`, a force from body back into parent coordinates.
    fn transpose_apply_force(&self, f: &LaneForce) -> LaneForce;
}

impl LaneTransform {
    /// Lane `l` set to the scalar transform `x`.
    pub(crate) fn set_lane(&mut self, l: usize, x: &Transform) {
        for r in 0..3 {
            for c in 0..3 {
                self.rot[r][c].0[l] = x.rot[(r, c)];
            }
            self.trans[r].0[l] = x.trans[r];
        }
    }
}

impl LaneSpatialTransform for LaneTransform {
    /// `X m = [E ω; E (v − r × ω)]` ([`Transform::apply_motion`]).
    #[inline(always)]
    fn apply_motion(&self, m: &LaneMotion) -> LaneMotion {
        LaneMotion {
            ang: mul(&self.rot, &m.ang),
            lin: mul(&self.rot, &(m.lin - self.trans.cross(&m.ang))),
        }
    }

    /// `Xᵀ f = [Eᵀ n + r × Eᵀ f; Eᵀ f]` ([`Transform::transpose_apply_force`]).
    #[inline(always)]
    fn transpose_apply_force(&self, f: &LaneForce) -> LaneForce {
        let lin = tr_mul(&self.rot, &f.lin);
        LaneForce {
            ang: tr_mul(&self.rot, &f.ang) + self.trans.cross(&lin),
            lin,
        }
    }
}

/// `xlt(r)` ([`Translation`](crate::spatial::Translation)).
pub(crate) struct LaneTranslation(pub(crate) V3);

impl LaneSpatialTransform for LaneTranslation {
    /// `xlt(r) m = [ω; v − r × ω]`.
    #[inline(always)]
    fn apply_motion(&self, m: &LaneMotion) -> LaneMotion {
        LaneMotion {
            ang: m.ang,
            lin: m.lin - self.0.cross(&m.ang),
        }
    }

    /// `xlt(r)ᵀ f = [n + r × f; f]`.
    #[inline(always)]
    fn transpose_apply_force(&self, f: &LaneForce) -> LaneForce {
        LaneForce {
            ang: f.ang + self.0.cross(&f.lin),
            lin: f.lin,
        }
    }
}

/// `rot(E_K(θ)) xlt(r)`, a turn about coordinate axis `K` after a translation
/// ([`AxisTransform`](crate::spatial::AxisTransform)): `E` has rows `c e_I + s e_J`,
/// `c e_J − s e_I`, `e_K` (`I = K + 1`, `J = K + 2` mod 3).
pub(crate) struct LaneAxisTurn<const K: usize> {
    pub(crate) cos: Lanes,
    pub(crate) sin: Lanes,
    pub(crate) trans: V3,
}

impl<const K: usize> LaneAxisTurn<K> {
    const I: usize = (K + 1) % 3;
    const J: usize = (K + 2) % 3;

    /// The turn read off a transform whose rotation is one about axis `K`: `c = E_II`,
    /// `s = E_IJ` (`AxisTransform::from_transform`).
    #[inline(always)]
    pub(crate) fn from_transform(x: &LaneTransform) -> Self {
        LaneAxisTurn {
            cos: x.rot[Self::I][Self::I],
            sin: x.rot[Self::I][Self::J],
            trans: x.trans,
        }
    }

    /// `E u`: `(c u_I + s u_J, c u_J − s u_I, u_K)` in the `(I, J, K)` slots.
    #[inline(always)]
    fn turn(&self, u: &V3) -> V3 {
        let (c, s) = (self.cos, self.sin);
        let mut out = *u;
        out[Self::I] = c * u[Self::I] + s * u[Self::J];
        out[Self::J] = c * u[Self::J] - s * u[Self::I];
        out
    }

    /// `Eᵀ u`: `(c u_I − s u_J, s u_I + c u_J, u_K)` in the `(I, J, K)` slots.
    #[inline(always)]
    fn turn_back(&self, u: &V3) -> V3 {
        let (c, s) = (self.cos, self.sin);
        let mut out = *u;
        out[Self::I] = c * u[Self::I] - s * u[Self::J];
        out[Self::J] = s * u[Self::I] + c * u[Self::J];
        out
    }
}

impl<const K: usize> LaneSpatialTransform for LaneAxisTurn<K> {
    /// `X m = [E ω; E (v − r × ω)]`: the translation, then the turn.
    #[inline(always)]
    fn apply_motion(&self, m: &LaneMotion) -> LaneMotion {
        let m = LaneTranslation(self.trans).apply_motion(m);
        LaneMotion {
            ang: self.turn(&m.ang),
            lin: self.turn(&m.lin),
        }
    }

    /// `Xᵀ f = xlt(r)ᵀ [Eᵀ n; Eᵀ f]`.
    #[inline(always)]
    fn transpose_apply_force(&self, f: &LaneForce) -> LaneForce {
        let turned = LaneForce {
            ang: self.turn_back(&f.ang),
            lin: self.turn_back(&f.lin),
        };
        LaneTranslation(self.trans).transpose_apply_force(&turned)
    }
}

/// Evaluates `$body` with `$x` bound to a body's lane `ⁱX_λ` (`&LaneTransform`) in the form
/// its joint's [`UpShape`](crate::model::UpShape) gives, as
/// `kinematics::with_up_transform` does for one state.
macro_rules! with_lane_transform {
    (shape: $shape:expr, x_up: $x_up:expr, |$x:ident| $body:expr) => {{
        use $crate::algorithms::lanes::spatial::{LaneAxisTurn, LaneTransform, LaneTranslation};
        use $crate::model::UpShape;
        let (shape, x_up): (UpShape, &LaneTransform) = ($shape, $x_up);
        match shape {
            UpShape::General => {
                let $x = x_up;
                $body
            }
            UpShape::Translation => {
                let $x = &LaneTranslation(x_up.trans);
                $body
            }
            UpShape::AxisTurn(0) => {
                let $x = &LaneAxisTurn::<0>::from_transform(x_up);
                $body
            }
            UpShape::AxisTurn(1) => {
                let $x = &LaneAxisTurn::<1>::from_transform(x_up);
                $body
            }
            UpShape::AxisTurn(_) => {
                let $x = &LaneAxisTurn::<2>::from_transform(x_up);
                $body
            }
        }
    }};
}
pub(crate) use with_lane_transform;
