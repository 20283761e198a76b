//! Joint kinds and `jcalc`: the only place that knows what each kind of joint does.

use crate::spatial::{sin_cos, Force, Matrix3, Motion, Transform, Vector3};
use nalgebra::{Rotation3, Unit};

/// The kinds of joint a body can hang from. Fixed joints never appear here: their child links
/// are fused into the parent body when the model is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointKind {
    /// Rotation by `q` about the unit `axis` (joint frame coordinates), limited.
    Revolute { axis: Vector3 },
    /// Rotation by `q` about the unit `axis`, unbounded; one angle (not cos/sin).
    Continuous { axis: Vector3 },
    /// Translation by `q` along the unit `axis`.
    Prismatic { axis: Vector3 },
    /// Motion in the plane normal to `normal`: `q = [x, y, θ]`, a translation `x u + y w` in the
    /// joint frame followed by a rotation θ about `normal`, with `u` the joint frame's x axis
    /// (or y axis if x is along the normal) projected on the plane and `w = normal × u`.
    /// Velocities are the time derivatives of `q` (`v = q̇`).
    Planar {
        normal: Vector3,
        u: Vector3,
        w: Vector3,
    },
    /// Six degrees of freedom: `q = [x y z qx qy qz qw]` (child origin in the joint frame and a
    /// unit quaternion of the child's orientation), `v = [linear; angular]`, the child's twist
    /// expressed in the child frame (nav_msgs/Odometry's convention; Pinocchio's free-flyer).
    Floating,
}

/// Motion subspace `S` of a joint, expressed in the child body frame: up to six columns.
#[derive(Clone, Copy, Debug, Default)]
pub struct MotionSubspace {
    /// The columns `S_k`; only the first `nv` are meaningful.
    pub cols: [Motion; 6],
    /// Number of columns (the joint's degrees of freedom).
    pub nv: usize,
}

impl MotionSubspace {
    /// `S q̇ = Σ_k S_k q̇_k`, with every rate scaled by `scale`.
    pub fn apply(&self, rates: &[f64], scale: f64) -> Motion {
        let mut m = Motion::zero();
        for (col, r) in self.cols[..self.nv].iter().zip(rates) {
            m += *col * (r * scale);
        }
        m
    }

    /// `Sᵀ f`, component `k`.
    pub fn project(&self, k: usize, f: &Force) -> f64 {
        self.cols[k].dot(f)
    }
}

impl JointKind {
    /// A planar kind moving in the plane normal to `normal` (normalised here; must be non-zero).
    pub fn planar(normal: Vector3) -> Self {
        let n = normal.normalize();
        let seed = if n.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let u = (seed - n * n.dot(&seed)).normalize();
        JointKind::Planar {
            normal: n,
            u,
            w: n.cross(&u),
        }
    }

    /// Number of position coordinates.
    pub fn nq(&self) -> usize {
        match self {
            JointKind::Revolute { .. }
            | JointKind::Continuous { .. }
            | JointKind::Prismatic { .. } => 1,
            JointKind::Planar { .. } => 3,
            JointKind::Floating => 7,
        }
    }

    /// Number of velocity coordinates.
    pub fn nv(&self) -> usize {
        match self {
            JointKind::Floating => 6,
            k => k.nq(),
        }
    }

    /// The neutral configuration into `q` (its `nq()` coordinates): zero for every kind but the
    /// floating joint, whose quaternion is the identity (`q = [0 0 0 0 0 0 1]`).
    pub fn neutral(&self, q: &mut [f64]) {
        q.fill(0.0);
        if *self == JointKind::Floating {
            q[6] = 1.0;
        }
    }

    /// The name used in URDF and on the command line.
    pub fn type_name(&self) -> &'static str {
        match self {
            JointKind::Revolute { .. } => "revolute",
            JointKind::Continuous { .. } => "continuous",
            JointKind::Prismatic { .. } => "prismatic",
            JointKind::Planar { .. } => "planar",
            JointKind::Floating => "floating",
        }
    }

    /// `jcalc`: the joint transform `X_J(q)` (joint frame → child body frame), returned, and the
    /// motion subspace `S(q)` in child body coordinates, written into `s` (its first `nv()`
    /// columns; in place, as it is 288 bytes). `q` holds this joint's `nq()` coordinates.
    pub fn jcalc(&self, q: &[f64], s: &mut MotionSubspace) -> Transform {
        s.nv = self.nv();
        match *self {
            JointKind::Revolute { axis } | JointKind::Continuous { axis } => {
                s.cols[0] = Motion::new(axis, Vector3::zeros());
                Transform::rotation(axis_rotation(&axis, q[0]).transpose())
            }
            JointKind::Prismatic { axis } => {
                s.cols[0] = Motion::new(Vector3::zeros(), axis);
                Transform::translation(axis * q[0])
            }
            JointKind::Planar { normal, u, w } => {
                let e = axis_rotation(&normal, q[2]).transpose();
                s.cols[0] = Motion::new(Vector3::zeros(), e * u);
                s.cols[1] = Motion::new(Vector3::zeros(), e * w);
                s.cols[2] = Motion::new(normal, Vector3::zeros());
                Transform {
                    rot: e,
                    trans: u * q[0] + w * q[1],
                }
            }
            JointKind::Floating => {
                floating_subspace(s);
                Transform::from_pose(&quaternion_rotation(q), &Vector3::new(q[0], q[1], q[2]))
            }
        }
    }

    /// `ⁱX_λ = X_J(q) X_tree` into `x_up`: `jcalc` composed with the joint placement `x_tree`
    /// (parent body frame → joint frame), writing `S(q)` into `s` as [`jcalc`](Self::jcalc)
    /// does.
    ///
    /// Fast paths, same result as `jcalc(q, s).compose(x_tree)`: a revolute joint about a
    /// coordinate axis `±e_k` has `E_J = rot_k(±q)ᵀ`, which mixes only the two rows `i, j` of
    /// `E_tree` other than `k` (`(i, j, k)` cyclic): `row_i ← c row_i + s row_j`,
    /// `row_j ← c row_j − s row_i`; it does not move the origin. A prismatic joint keeps
    /// `E_tree` and moves the origin by `E_treeᵀ (axis q)`. Inlined, and written in place by
    /// each path: a transform returned from the paths would be assembled in a temporary and
    /// copied with loads that straddle its stores, which the processor cannot forward (a stall
    /// per joint).
    #[inline]
    pub fn jcalc_up(
        &self,
        q: &[f64],
        x_tree: &Transform,
        s: &mut MotionSubspace,
        x_up: &mut Transform,
    ) {
        let turn = sin_cos(self.turn_angle(q));
        self.jcalc_up_turned(q, turn, x_tree, s, x_up);
    }

    /// `Some((k, σ))` for a revolute joint about a coordinate axis `σ e_k`: a joint whose
    /// `ⁱX_λ` [`turn_up`] gives from the sine and cosine of its turn angle `σ q`, and whose `S`
    /// is constant.
    pub fn turn_axis(&self) -> Option<(usize, f64)> {
        match *self {
            JointKind::Revolute { axis } | JointKind::Continuous { axis } => coordinate_axis(&axis),
            _ => None,
        }
    }

    /// The angle a revolute joint about a coordinate axis `σ e_k` turns its body's axes by,
    /// `σ q` (the sine and cosine [`jcalc_up_turned`](Self::jcalc_up_turned) takes); 0 for any
    /// other joint.
    #[inline]
    pub fn turn_angle(&self, q: &[f64]) -> f64 {
        self.turn_axis().map_or(0.0, |(_, sign)| sign * q[0])
    }

    /// [`jcalc_up`](Self::jcalc_up) given `(sin, cos)` of [`turn_angle`](Self::turn_angle)
    /// (which other joints ignore): `kinematics::update_joints` computes them for all joints
    /// at once (`spatial::sin_cos_all`).
    #[inline]
    pub fn jcalc_up_turned(
        &self,
        q: &[f64],
        (sin, cos): (f64, f64),
        x_tree: &Transform,
        s: &mut MotionSubspace,
        x_up: &mut Transform,
    ) {
        match *self {
            JointKind::Revolute { axis } | JointKind::Continuous { axis } => {
                if let Some((k, _)) = coordinate_axis(&axis) {
                    s.nv = 1;
                    s.cols[0] = Motion::new(axis, Vector3::zeros());
                    turn_up(k, (sin, cos), x_tree, x_up);
                    return;
                }
            }
            JointKind::Prismatic { axis } => {
                s.nv = 1;
                s.cols[0] = Motion::new(Vector3::zeros(), axis);
                x_up.rot = x_tree.rot;
                x_up.trans = x_tree.trans + x_tree.rot.tr_mul(&(axis * q[0]));
                return;
            }
            JointKind::Floating => {
                floating_subspace(s);
                floating_up(q, x_tree, x_up);
                return;
            }
            _ => {}
        }
        *x_up = self.jcalc_then_compose(q, x_tree, s);
    }

    /// What [`jcalc_up`](Self::jcalc_up)'s transform is made of for this joint under the
    /// placement `x_tree`, whatever `q`: a placement without rotation (`E_tree = 1` exactly, a
    /// URDF `rpy="0 0 0"`, the common case) leaves a revolute joint about `±e_k` a turn about
    /// `e_k` after a translation and a prismatic joint a translation.
    pub fn up_shape(&self, x_tree: &Transform) -> UpShape {
        if x_tree.rot != Matrix3::identity() {
            return UpShape::General;
        }
        match *self {
            JointKind::Revolute { axis } | JointKind::Continuous { axis } => {
                match coordinate_axis(&axis) {
                    Some((k, _)) => UpShape::AxisTurn(k),
                    None => UpShape::General,
                }
            }
            JointKind::Prismatic { .. } => UpShape::Translation,
            _ => UpShape::General,
        }
    }

    /// The general case of [`jcalc_up`](Self::jcalc_up), kept out of line.
    #[inline(never)]
    fn jcalc_then_compose(
        &self,
        q: &[f64],
        x_tree: &Transform,
        s: &mut MotionSubspace,
    ) -> Transform {
        self.jcalc(q, s).compose(x_tree)
    }

    /// The columns of `S` (child body coordinates) that are a signed unit vector of `[ω; v]`
    /// whatever `q`: `Some((j, σ))` when column `k` is `σ e_j` (`j` in `0..6`, angular first),
    /// so that `S_kᵀ f = σ f_j` and `I S_k = σ I e_j`. A revolute joint about `±e_k` has its
    /// one column on `k`, a prismatic joint along `±e_k` on `3 + k`, the floating joint's
    /// `S = [0 1; 1 0]` (`v = [linear; angular]`) is all axes, and a planar joint's rotation
    /// column is one when its normal is a coordinate axis (its translation columns turn with θ).
    pub fn subspace_axes(&self) -> [Option<(usize, f64)>; 6] {
        let mut axes = [None; 6];
        match *self {
            JointKind::Revolute { axis } | JointKind::Continuous { axis } => {
                axes[0] = coordinate_axis(&axis);
            }
            JointKind::Prismatic { axis } => {
                axes[0] = coordinate_axis(&axis).map(|(k, sign)| (3 + k, sign));
            }
            JointKind::Planar { normal, .. } => axes[2] = coordinate_axis(&normal),
            JointKind::Floating => {
                for k in 0..3 {
                    (axes[k], axes[k + 3]) = (Some((3 + k, 1.0)), Some((k, 1.0)));
                }
            }
        }
        axes
    }

    /// The velocity-product term `c_J = S̊(q) q̇` (the apparent derivative of `S` in the child
    /// frame times `q̇`); `None` (zero) for every kind whose `S` is constant in the child frame,
    /// so that a pass adds nothing. `qd` holds the joint's velocity coordinates, already scaled.
    pub fn bias(&self, q: &[f64], qd: &[f64]) -> Option<Motion> {
        match *self {
            JointKind::Planar { normal, u, w } => {
                // S = [0 0 n; E u  E w  0] with E = R(θ)ᵀ; d(E)/dt = −θ̇ n× E, so
                // c_J = [0; −θ̇ n × E (ẋ u + ẏ w)].
                let e = axis_rotation(&normal, q[2]).transpose();
                let planar_velocity = e * (u * qd[0] + w * qd[1]);
                Some(Motion::new(
                    Vector3::zeros(),
                    -normal.cross(&planar_velocity) * qd[2],
                ))
            }
            _ => None,
        }
    }
}

impl JointKind {
    /// `q ⊕ v·dt`: the configuration reached from `q` moving with constant velocity `v` for
    /// `dt`, on the joint's manifold. For a floating joint the body twist is integrated exactly
    /// (SE(3) exponential) and the quaternion renormalised; every other kind adds `v·dt`.
    pub fn integrate(&self, q: &[f64], v: &[f64], dt: f64, out: &mut [f64]) {
        match self {
            JointKind::Floating => integrate_floating(q, v, dt, out),
            _ => {
                for ((o, x), r) in out.iter_mut().zip(q).zip(v) {
                    *o = x + r * dt;
                }
            }
        }
    }
}

/// A floating joint's `q ⊕ v·dt` (`q = [p; x y z w]`, `v = [v_B; ω_B]` in the body frame): with
/// `ψ = ω_B dt`, `θ = |ψ|`, the SE(3) exponential of the body twist `dt [v_B; ω_B]` gives
/// ```text
/// p' = p + R V(ψ) v_B dt,   V(ψ) = 1 + a ψ× + b ψ×²,   a = (1 − cos θ)/θ²,  b = (θ − sin θ)/θ³,
/// R' = R exp(ψ),            exp(ψ) = [cos θ/2; h ψ]  (quaternion, w first),  h = sin(θ/2)/θ,
/// ```
/// `R'` renormalised. The quaternion of `q` may have any norm (the library normalises it, as
/// everywhere): `R x = (q x q*)/|q|²`, [`quaternion_rotation`]'s matrix applied without being
/// built, which is faster (docs/performance.md, "Simulation against MuJoCo"). The coefficients
/// are [`exp_coefficients`].
fn integrate_floating(q: &[f64], v: &[f64], dt: f64, out: &mut [f64]) {
    let (w, u) = (q[6], Vector3::new(q[3], q[4], q[5]));
    let lin = Vector3::new(v[0], v[1], v[2]) * dt;
    let psi = Vector3::new(v[3], v[4], v[5]) * dt;
    let [a, b, c, h] = exp_coefficients(psi.norm_squared());
    let turned = psi.cross(&lin);
    let step = lin + turned * a + psi.cross(&turned) * b;
    // q x q* = (w² − u·u) x + 2 (u·x) u + 2 w u × x
    let uu = u.norm_squared();
    let rotated = step * (w * w - uu) + u * (2.0 * u.dot(&step)) + u.cross(&step) * (2.0 * w);
    let p = Vector3::new(q[0], q[1], q[2]) + rotated * (1.0 / (w * w + uu));
    // q exp(ψ) = [w c − u·e; w e + c u + u × e] with e = h ψ
    let e = psi * h;
    let (w_moved, u_moved) = (w * c - u.dot(&e), e * w + u * c + u.cross(&e));
    let scale = 1.0 / (w_moved * w_moved + u_moved.norm_squared()).sqrt();
    out[..3].copy_from_slice(p.as_slice());
    out[3..6].copy_from_slice((u_moved * scale).as_slice());
    out[6] = w_moved * scale;
}

/// `[a, b, c, h]` of [`integrate_floating`] for `x = θ²`: `a = (1 − cos θ)/θ²`,
/// `b = (θ − sin θ)/θ³`, `c = cos(θ/2)`, `h = sin(θ/2)/θ`. For `θ ≤ 0.2` (a step turning the
/// body by 0.2 rad: 200 rad/s at 1 ms) each is its Taylor series in `x` to `x⁵`, whose first
/// term left out is below `10⁻¹⁹` of the sum: no square root, division or cancellation. Above,
/// from one [`sin_cos`] of `θ/2`: `sin θ = 2 s c` and `1 − cos θ = 2 s²`.
fn exp_coefficients(x: f64) -> [f64; 4] {
    if x <= SERIES_LIMIT {
        let series = |coeffs: &[f64; 6]| coeffs.iter().rev().fold(0.0, |sum, k| sum * x + k);
        return [
            series(&SERIES[0]),
            series(&SERIES[1]),
            series(&SERIES[2]),
            series(&SERIES[3]),
        ];
    }
    let theta = x.sqrt();
    let (s, c) = sin_cos(0.5 * theta);
    let r = 1.0 / theta;
    let h = s * r;
    [2.0 * h * h, (theta - 2.0 * s * c) * (r * r * r), c, h]
}

/// `θ² = 0.04`: below it [`exp_coefficients`] sums series.
const SERIES_LIMIT: f64 = 0.04;

/// The Taylor coefficients of [`exp_coefficients`]' `a`, `b`, `c`, `h` in `x = θ²`, `k = 0, …, 5`:
/// `(−1)ᵏ/(2k+2)!`, `(−1)ᵏ/(2k+3)!`, `(−1)ᵏ/(4ᵏ (2k)!)`, `(−1)ᵏ/(2·4ᵏ (2k+1)!)`.
const SERIES: [[f64; 6]; 4] = [
    [
        1.0 / 2.0,
        -1.0 / 24.0,
        1.0 / 720.0,
        -1.0 / 40320.0,
        1.0 / 3628800.0,
        -1.0 / 479001600.0,
    ],
    [
        1.0 / 6.0,
        -1.0 / 120.0,
        1.0 / 5040.0,
        -1.0 / 362880.0,
        1.0 / 39916800.0,
        -1.0 / 6227020800.0,
    ],
    [
        1.0,
        -1.0 / 8.0,
        1.0 / 384.0,
        -1.0 / 46080.0,
        1.0 / 10321920.0,
        -1.0 / 3715891200.0,
    ],
    [
        1.0 / 2.0,
        -1.0 / 48.0,
        1.0 / 3840.0,
        -1.0 / 645120.0,
        1.0 / 185794560.0,
        -1.0 / 81749606400.0,
    ],
];

/// The form of a body's `ⁱX_λ` known when the model is built ([`JointKind::up_shape`]), so that
/// a pass can use the cheaper actions of [`Translation`](crate::spatial::Translation) and
/// [`AxisTransform`](crate::spatial::AxisTransform) instead of a general transform's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpShape {
    /// Any rotation and translation.
    General,
    /// `xlt(r)`: no rotation.
    Translation,
    /// `rot(E_k(θ)) xlt(r)`: a turn about coordinate axis `k` after a translation.
    AxisTurn(usize),
}

/// `ⁱX_λ = X_J X_tree` of a revolute joint about `σ e_k` ([`JointKind::turn_axis`]), given
/// `(sin, cos)` of its turn angle `σ q`: `E_J = rot_k(σ q)ᵀ` mixes the two rows of `E_tree`
/// other than `k`, and the origin stays (see [`JointKind::jcalc_up`]). Written in place.
#[inline(always)]
pub fn turn_up(k: usize, turn: (f64, f64), x_tree: &Transform, x_up: &mut Transform) {
    x_up.rot = turned(k, turn, &x_tree.rot);
    x_up.trans = x_tree.trans;
}

/// `E_J E` for a turn about coordinate axis `k` given `(sin, cos)` of its angle: the two rows
/// of `E` other than `k` mixed (`row_I ← c row_I + s row_J`, `row_J ← c row_J − s row_I`,
/// `I = k + 1`, `J = k + 2` mod 3), row `k` kept.
#[inline(always)]
pub fn turned(k: usize, (sin, cos): (f64, f64), e: &Matrix3) -> Matrix3 {
    // One arm per axis, so that the rows are known at compile time.
    match k {
        0 => mix_rows::<1, 2>(e, cos, sin),
        1 => mix_rows::<2, 0>(e, cos, sin),
        _ => mix_rows::<0, 1>(e, cos, sin),
    }
}

/// [`turn_up`] for a placement without rotation (`E_tree = 1`, the joints of shape
/// [`UpShape::AxisTurn`]): `E_J` itself, rows `I`, `J` of the identity mixed by the turn
/// (`row_I = c e_I + s e_J`, `row_J = c e_J − s e_I`), written without a product.
#[inline(always)]
pub fn turn_up_unrotated(
    k: usize,
    (sin, cos): (f64, f64),
    x_tree: &Transform,
    x_up: &mut Transform,
) {
    x_up.rot = match k {
        0 => turn_rows::<1, 2>(cos, sin),
        1 => turn_rows::<2, 0>(cos, sin),
        _ => turn_rows::<0, 1>(cos, sin),
    };
    x_up.trans = x_tree.trans;
}

/// The identity with its rows `I` and `J` mixed by a rotation, [`mix_rows`] of the identity.
#[inline(always)]
fn turn_rows<const I: usize, const J: usize>(c: f64, s: f64) -> Matrix3 {
    Matrix3::from_fn(|r, col| match (r, col) {
        _ if r == col && (r == I || r == J) => c,
        _ if r == col => 1.0,
        _ if (r, col) == (I, J) => s,
        _ if (r, col) == (J, I) => -s,
        _ => 0.0,
    })
}

/// `E` with its rows `I` and `J` mixed by a rotation: `row_I ← c row_I + s row_J`,
/// `row_J ← c row_J − s row_I`, the others kept.
#[inline(always)]
fn mix_rows<const I: usize, const J: usize>(e: &Matrix3, c: f64, s: f64) -> Matrix3 {
    Matrix3::from_fn(|r, col| {
        if r == I {
            c * e[(I, col)] + s * e[(J, col)]
        } else if r == J {
            c * e[(J, col)] - s * e[(I, col)]
        } else {
            e[(r, col)]
        }
    })
}

/// `Some((k, ±1))` when the unit `axis` is `±e_k`, a coordinate axis.
fn coordinate_axis(axis: &Vector3) -> Option<(usize, f64)> {
    match (axis.x, axis.y, axis.z) {
        (x, 0.0, 0.0) if x.abs() == 1.0 => Some((0, x)),
        (0.0, y, 0.0) if y.abs() == 1.0 => Some((1, y)),
        (0.0, 0.0, z) if z.abs() == 1.0 => Some((2, z)),
        _ => None,
    }
}

/// Rotation matrix of angle `angle` about the unit vector `axis`.
pub fn axis_rotation(axis: &Vector3, angle: f64) -> Matrix3 {
    Rotation3::from_axis_angle(&Unit::new_unchecked(*axis), angle).into_inner()
}

/// The floating joint's constant `S = [0 1; 1 0]` (`v = [linear; angular]` in body
/// coordinates).
fn floating_subspace(s: &mut MotionSubspace) {
    s.nv = 6;
    for k in 0..3 {
        s.cols[k] = Motion::new(Vector3::zeros(), Vector3::ith(k, 1.0));
        s.cols[k + 3] = Motion::new(Vector3::ith(k, 1.0), Vector3::zeros());
    }
}

/// A floating joint's `ⁱX_λ = X_J X_tree` without its `S` (constant, `floating_subspace`):
/// `X_J` has `E_J = Rᵀ` (`R` from the quaternion `q[3..7]`, [`quaternion_rotation`]) and the
/// origin `p = q[0..3]`, so `E = Rᵀ E_tree` and `r = r_tree + E_treeᵀ p`.
#[inline(always)]
pub fn floating_up(q: &[f64], x_tree: &Transform, x_up: &mut Transform) {
    let r = quaternion_rotation(q);
    x_up.rot = r.tr_mul(&x_tree.rot);
    x_up.trans = x_tree.trans + x_tree.rot.tr_mul(&Vector3::new(q[0], q[1], q[2]));
}

/// Rotation matrix of the (normalised) quaternion stored at `q[3..7]` as (x, y, z, w):
/// with `σ = 2 / (x² + y² + z² + w²)` (normalising without a square root),
///
/// ```text
/// R = [1 − σ(y² + z²)   σ(xy − wz)       σ(xz + wy)    ]
///     [σ(xy + wz)       1 − σ(x² + z²)   σ(yz − wx)    ]
///     [σ(xz − wy)       σ(yz + wx)       1 − σ(x² + y²)]
/// ```
#[inline]
pub fn quaternion_rotation(q: &[f64]) -> Matrix3 {
    let (x, y, z, w) = (q[3], q[4], q[5], q[6]);
    let sigma = 2.0 / (x * x + y * y + z * z + w * w);
    let (xs, ys, zs) = (x * sigma, y * sigma, z * sigma);
    let (wx, wy, wz) = (w * xs, w * ys, w * zs);
    let (xx, xy, xz) = (x * xs, x * ys, x * zs);
    let (yy, yz, zz) = (y * ys, y * zs, z * zs);
    Matrix3::new(
        1.0 - (yy + zz),
        xy - wz,
        xz + wy,
        xy + wz,
        1.0 - (xx + zz),
        yz - wx,
        xz - wy,
        yz + wx,
        1.0 - (xx + yy),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Quaternion, UnitQuaternion};

    /// The fast paths of `jcalc_up` give what the general `jcalc` composed with `X_tree` gives.
    #[test]
    fn jcalc_up_matches_jcalc_then_compose() {
        let x_tree = Transform::from_pose(
            Rotation3::from_euler_angles(0.4, -1.1, 2.0).matrix(),
            &Vector3::new(0.3, -0.2, 0.7),
        );
        let mut kinds = vec![JointKind::Prismatic {
            axis: Vector3::new(0.0, 0.6, 0.8),
        }];
        for k in 0..3 {
            for sign in [1.0, -1.0] {
                kinds.push(JointKind::Revolute {
                    axis: Vector3::ith(k, sign),
                });
                kinds.push(JointKind::Prismatic {
                    axis: Vector3::ith(k, sign),
                });
            }
        }
        for kind in kinds {
            let q = [0.83];
            let (mut s_fast, mut s_ref) = (MotionSubspace::default(), MotionSubspace::default());
            let mut fast = Transform::identity();
            kind.jcalc_up(&q, &x_tree, &mut s_fast, &mut fast);
            let reference = kind.jcalc(&q, &mut s_ref).compose(&x_tree);
            assert!((fast.rot - reference.rot).norm() < 1e-15, "{kind:?}");
            assert!((fast.trans - reference.trans).norm() < 1e-15, "{kind:?}");
            assert_eq!(s_fast.nv, s_ref.nv);
            assert_eq!(s_fast.cols[0], s_ref.cols[0]);
        }
    }

    /// A floating joint's `q ⊕ v·dt` is the pose `[R p; 0 1] expm(dt [ω×  v; 0 0])`, the 4×4
    /// matrix exponential (nalgebra's Padé approximant, no trigonometry) of the body twist: on
    /// both sides of the series' limit (`θ = 0.2`) and at the trigonometric range, from a
    /// quaternion of norm 3 (normalised as everywhere). Position and rotation within 1e-14.
    #[test]
    fn floating_integrate_is_the_exponential_of_the_twist() {
        let (p, quat) = (Vector3::new(0.3, -1.2, 0.5), [1.0, -2.0, 0.0, 2.0]);
        let norm = quat.iter().map(|x| x * x).sum::<f64>().sqrt();
        let r =
            UnitQuaternion::from_quaternion(Quaternion::new(quat[3], quat[0], quat[1], quat[2]))
                .to_rotation_matrix()
                .into_inner();
        assert!((norm - 3.0).abs() < 1e-12);
        let direction = Vector3::new(0.4, -0.3, 0.5).normalize();
        for theta in [0.0, 1e-9, 1e-3, 0.05, 0.1999, 0.2, 0.2001, 0.7, 2.5] {
            let dt = 0.01;
            let (lin, ang) = (Vector3::new(1.0, -0.5, 2.0), direction * (theta / dt));
            let mut twist = nalgebra::Matrix4::zeros();
            twist
                .fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&(crate::spatial::skew(&ang) * dt));
            twist.fixed_view_mut::<3, 1>(0, 3).copy_from(&(lin * dt));
            let mut pose = nalgebra::Matrix4::identity();
            pose.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
            pose.fixed_view_mut::<3, 1>(0, 3).copy_from(&p);
            let expected = pose * twist.exp();
            let q = [p.x, p.y, p.z, quat[0], quat[1], quat[2], quat[3]];
            let v = [lin.x, lin.y, lin.z, ang.x, ang.y, ang.z];
            let mut out = [0.0; 7];
            JointKind::Floating.integrate(&q, &v, dt, &mut out);
            let moved = Quaternion::new(out[6], out[3], out[4], out[5]);
            assert!((moved.norm() - 1.0).abs() < 1e-15, "θ = {theta}");
            let rotation = UnitQuaternion::new_unchecked(moved).to_rotation_matrix();
            let dr = (rotation.matrix() - expected.fixed_view::<3, 3>(0, 0)).amax();
            let dp =
                (Vector3::new(out[0], out[1], out[2]) - expected.fixed_view::<3, 1>(0, 3)).amax();
            assert!(
                dr < 1e-14 && dp < 1e-14,
                "θ = {theta}: ΔR {dr:e}, Δp {dp:e}"
            );
        }
    }

    /// `S` must be the derivative of the joint placement: the child's velocity obtained by
    /// differentiating `X_J(q)` numerically equals `S q̇` — checks each kind's `jcalc`.
    #[test]
    fn subspace_is_the_derivative_of_the_placement() {
        let kinds = [
            JointKind::Revolute {
                axis: Vector3::new(1.0, 2.0, -0.5).normalize(),
            },
            JointKind::Prismatic {
                axis: Vector3::new(0.0, -1.0, 1.0).normalize(),
            },
            JointKind::planar(Vector3::new(0.0, -1.0, 0.0)),
        ];
        for kind in kinds {
            let n = kind.nq();
            let q: Vec<f64> = (0..n).map(|i| 0.3 + 0.4 * i as f64).collect();
            let qd: Vec<f64> = (0..n).map(|i| -0.7 + 0.5 * i as f64).collect();
            let h = 1e-6;
            let step = |s: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, b)| a + s * b).collect() };
            let mut s = MotionSubspace::default();
            let mut scratch = MotionSubspace::default();
            let x0 = kind.jcalc(&q, &mut s);
            let xp = kind.jcalc(&step(h), &mut scratch);
            let xm = kind.jcalc(&step(-h), &mut scratch);
            // Child pose in joint frame: R = Eᵀ, p = r. Body-frame twist: ω× = Rᵀ Ṙ, v = Rᵀ ṗ.
            let r = x0.rot.transpose();
            let r_dot = (xp.rot.transpose() - xm.rot.transpose()) / (2.0 * h);
            let p_dot = (xp.trans - xm.trans) / (2.0 * h);
            let w = r.transpose() * r_dot;
            let twist = Motion::new(
                Vector3::new(w[(2, 1)], w[(0, 2)], w[(1, 0)]),
                r.transpose() * p_dot,
            );
            let expected = s.apply(&qd, 1.0);
            assert!(
                (twist.to_vector() - expected.to_vector()).norm() < 1e-8,
                "{kind:?}: {twist:?} vs {expected:?}"
            );
        }
    }

    /// Every column `subspace_axes` names is that signed unit vector in `jcalc`'s `S`, at any
    /// `q`; a column it does not name is not one.
    #[test]
    fn subspace_axes_match_jcalc() {
        let kinds = [
            JointKind::Revolute {
                axis: Vector3::new(0.0, -1.0, 0.0),
            },
            JointKind::Revolute {
                axis: Vector3::new(1.0, 2.0, -0.5).normalize(),
            },
            JointKind::Continuous { axis: Vector3::x() },
            JointKind::Prismatic {
                axis: Vector3::new(0.0, 0.0, -1.0),
            },
            JointKind::planar(Vector3::z()),
            JointKind::planar(Vector3::new(1.0, 1.0, 0.0)),
            JointKind::Floating,
        ];
        for kind in kinds {
            let axes = kind.subspace_axes();
            for q0 in [0.0, 0.4, -2.1] {
                let mut q = [q0, -0.5 * q0, 0.3, 0.1, -0.2, 0.3, 0.9];
                if kind == JointKind::Floating {
                    let norm = q[3..].iter().map(|x| x * x).sum::<f64>().sqrt();
                    q[3..].iter_mut().for_each(|x| *x /= norm);
                }
                let mut s = MotionSubspace::default();
                kind.jcalc(&q[..kind.nq()], &mut s);
                for (k, (col, axis)) in s.cols[..s.nv].iter().zip(axes).enumerate() {
                    let column = col.to_vector();
                    let unit = (0..6).find(|&j| {
                        column
                            .iter()
                            .enumerate()
                            .all(|(i, &x)| x.abs() == if i == j { 1.0 } else { 0.0 })
                    });
                    match axis {
                        Some((j, sign)) => {
                            assert_eq!((unit, column[j]), (Some(j), sign), "{kind:?} column {k}")
                        }
                        None => assert!(
                            unit.is_none() || matches!(kind, JointKind::Planar { .. }),
                            "{kind:?} column {k} is an axis"
                        ),
                    }
                }
                assert!(axes[s.nv..].iter().all(Option::is_none), "{kind:?}");
            }
        }
    }
}
