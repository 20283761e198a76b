//! Ground contact for the scenes that need it: a horizontal plane `z = height` (world frame) and
//! named points on named links, each pushed by a penalty spring–damper with smoothed Coulomb
//! friction, applied to the bodies as external wrenches. A scene without contact points pays
//! nothing for it.
//!
//! For a point at depth `d = height − z > 0` moving with world velocity `u`:
//! `f_n = max(0, k d − b u_z)`, `f_t = −μ f_n u_t / √(|u_t|² + ε²)` (ε = 0.01 m/s), the force
//! `[f_t; f_n]` acts at the point.

use crate::algorithms::kinematics::body_motion;
use crate::error::DynamicsError;
use crate::spatial::{Force, Vector3};
use crate::{Model, Workspace};

/// A contact point: a link name and a point in that link's frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactPoint {
    pub link: String,
    pub point: Vector3,
}

impl std::str::FromStr for ContactPoint {
    type Err = String;
    /// `LINK:X,Y,Z`, the point in the link's frame (m).
    fn from_str(spec: &str) -> Result<ContactPoint, String> {
        spec.split_once(':')
            .and_then(|(link, xyz)| {
                let v: Vec<f64> = xyz
                    .split(',')
                    .map(|x| x.trim().parse().ok())
                    .collect::<Option<_>>()?;
                (!link.is_empty() && v.len() == 3 && v.iter().all(|x| x.is_finite())).then(|| {
                    ContactPoint {
                        link: link.to_string(),
                        point: Vector3::new(v[0], v[1], v[2]),
                    }
                })
            })
            .ok_or_else(|| format!("contact point '{spec}': expected LINK:X,Y,Z (finite, m)"))
    }
}

impl std::fmt::Display for ContactPoint {
    /// As parsed: `LINK:X,Y,Z`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = &self.point;
        write!(f, "{}:{:?},{:?},{:?}", self.link, p.x, p.y, p.z)
    }
}

/// The ground and the points that can touch it.
#[derive(Clone, Debug, PartialEq)]
pub struct Ground {
    /// Height of the plane (m, world z).
    pub height: f64,
    /// Spring stiffness k (N/m) and damping b (N·s/m) per point.
    pub stiffness: f64,
    pub damping: f64,
    /// Friction coefficient μ.
    pub friction: f64,
    pub points: Vec<ContactPoint>,
}

impl Default for Ground {
    fn default() -> Self {
        Ground {
            height: 0.0,
            stiffness: 2e4,
            damping: 200.0,
            friction: 0.8,
            points: Vec::new(),
        }
    }
}

impl Ground {
    /// The plane's numbers are usable: finite height, stiffness > 0, damping and friction ≥ 0.
    /// The error names the field and its value.
    pub fn check(&self) -> Result<(), String> {
        for (field, value, least) in [
            ("height", self.height, f64::NEG_INFINITY),
            ("stiffness", self.stiffness, f64::MIN_POSITIVE),
            ("damping", self.damping, 0.0),
            ("friction", self.friction, 0.0),
        ] {
            if !(value.is_finite() && value >= least) {
                let want = if least > 0.0 {
                    "> 0"
                } else if least == 0.0 {
                    "≥ 0"
                } else {
                    "finite"
                };
                return Err(format!("ground {field} is {value}: it must be {want}"));
            }
        }
        Ok(())
    }
}

/// Tangential smoothing velocity of contact friction (m/s).
pub const CONTACT_FRICTION_SMOOTHING: f64 = 0.01;

/// Contact points resolved to bodies, and the wrenches they produce.
#[derive(Clone, Debug)]
pub(crate) struct Contacts {
    ground: Ground,
    /// `(body, point in the body frame)` per contact point.
    points: Vec<(usize, Vector3)>,
    wrenches: Vec<Force>,
    /// Deepest penetration at the latest evaluation (m), a state the step may not keep (an RK
    /// stage, a Newton probe) until [`Contacts::keep_penetration`] says it is one it keeps.
    latest_penetration: f64,
    /// Deepest penetration of the states kept (m).
    pub max_penetration: f64,
}

impl Contacts {
    /// Resolves each point's link to its body (fused links included).
    pub(crate) fn new(model: &Model, ground: &Ground) -> Result<Contacts, String> {
        ground.check()?;
        let mut points = Vec::new();
        for p in &ground.points {
            let link = model
                .link(&p.link)
                .ok_or_else(|| format!("contact point on unknown link '{}'", p.link))?;
            let body = link.body.ok_or_else(|| {
                format!(
                    "contact point on link '{}', which is fixed to the world",
                    p.link
                )
            })?;
            // Point in link frame → body frame: x_body_link maps body to link coordinates.
            let x = &link.x_body_link;
            points.push((body, x.trans + x.rot.tr_mul(&p.point)));
        }
        Ok(Contacts {
            ground: ground.clone(),
            points,
            wrenches: vec![Force::zero(); model.nbodies()],
            latest_penetration: 0.0,
            max_penetration: 0.0,
        })
    }

    /// The latest evaluation was at a state of the trajectory: its penetration counts.
    pub(crate) fn keep_penetration(&mut self) {
        self.max_penetration = self.max_penetration.max(self.latest_penetration);
    }

    /// True when there is nothing to compute.
    pub(crate) fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The contact wrench on every body (body frames) at `(q, v)`.
    pub(crate) fn wrenches(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        q: &[f64],
        v: &[f64],
    ) -> Result<&[Force], DynamicsError> {
        self.wrenches.iter_mut().for_each(|w| *w = Force::zero());
        self.latest_penetration = 0.0;
        body_motion(model, ws, q, v)?;
        let g = &self.ground;
        for &(body, p) in &self.points {
            let x = ws.world_to_body(body);
            let position = x.trans + x.rot.tr_mul(&p);
            let depth = g.height - position.z;
            if depth <= 0.0 {
                continue;
            }
            self.latest_penetration = self.latest_penetration.max(depth);
            let twist = ws.body_velocity(body);
            let velocity = x.rot.tr_mul(&(twist.lin + twist.ang.cross(&p)));
            let normal = (g.stiffness * depth - g.damping * velocity.z).max(0.0);
            let slip = Vector3::new(velocity.x, velocity.y, 0.0);
            let tangential = -slip
                * (g.friction * normal
                    / (slip.norm_squared() + CONTACT_FRICTION_SMOOTHING.powi(2)).sqrt());
            let force_body = x.rot * (tangential + Vector3::new(0.0, 0.0, normal));
            self.wrenches[body] += Force::new(p.cross(&force_body), force_body);
        }
        Ok(&self.wrenches)
    }
}
