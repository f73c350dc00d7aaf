//! The collision sections of robot and design files (obstacles, attached
//! shapes, allowed pairs, margins) and the robot's geometry built from them.

use super::shape::{Body, ShapeSpec};
use serde::{Deserialize, Serialize};

/// A pair of bodies the robot file declares as never to be checked.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AllowedCollision {
    /// First link.
    pub a: String,
    /// Second link.
    pub b: String,
    /// Why the pair cannot collide or may touch (required).
    pub reason: String,
}

// ---------------------------------------------------------------------------
// The robot's geometry
// ---------------------------------------------------------------------------

/// The collision geometry of a robot, built once at load: one body per moving
/// link (everything fixed to it merged in: fixed child links, tool flanges,
/// the hand and fingers) and one for the base.
#[derive(Debug, Clone)]
pub struct RobotGeometry {
    /// Body 0 is the base, body i + 1 moves with link i.
    pub bodies: Vec<Body>,
    /// URDF link names merged into each body (for `allowed_collision` and messages).
    pub members: Vec<Vec<String>>,
    /// Pairs the robot file excludes, with their reasons.
    pub allowed: Vec<AllowedCollision>,
    /// Where the geometry came from (for reports).
    pub source: String,
}

impl RobotGeometry {
    /// Body index of a link name (a moving link, the base or any link merged into one).
    pub fn body_of(&self, name: &str) -> Option<usize> {
        self.members.iter().position(|m| m.iter().any(|x| x == name))
    }
}

/// Which class a checked pair belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PairClass {
    /// Two bodies of the robot.
    SelfCollision,
    /// A robot body and an obstacle (floor, cell).
    World,
}

impl PairClass {
    /// `self` or `world`.
    pub fn label(self) -> &'static str {
        match self {
            PairClass::SelfCollision => "self",
            PairClass::World => "world",
        }
    }
}

/// One checked pair of a scene.
#[derive(Debug, Clone, Serialize)]
pub struct PairInfo {
    /// Name of the first body.
    pub a: String,
    /// Name of the second body.
    pub b: String,
    /// Self or world.
    pub class: PairClass,
    #[serde(skip)]
    pub(super) ia: usize,
    #[serde(skip)]
    pub(super) ib: usize,
}

impl PairInfo {
    /// `self: forearm_link – wrist_2_link`.
    pub fn label(&self) -> String {
        format!("{}: {} – {}", self.class.label(), self.a, self.b)
    }
}

/// A pair left out, and why.
#[derive(Debug, Clone, Serialize)]
pub struct ExcludedPair {
    /// First body.
    pub a: String,
    /// Second body.
    pub b: String,
    /// Why.
    pub reason: String,
}

fn yes() -> bool {
    true
}

fn default_margin() -> f64 {
    0.02
}

fn default_band() -> f64 {
    0.1
}

/// A fixed obstacle of the cell (`[[collision.obstacle]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// Name in reports.
    pub name: String,
    /// Shape.
    pub shape: ShapeSpec,
    /// Position in the base frame (m).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation (roll, pitch, yaw; rad).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// A tool or payload shape fixed to a frame of the robot (`[[collision.attached]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttachedSpec {
    /// Name in reports.
    pub name: String,
    /// Frame or link it is fixed to.
    pub frame: String,
    /// Shape (not a plane).
    pub shape: ShapeSpec,
    /// Position in the frame (m).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation in the frame (rad).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// The `[collision]` section of a design file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionSpec {
    /// Check collisions at all (default true; without robot geometry there is nothing to check).
    #[serde(default = "yes")]
    pub enabled: bool,
    /// Required minimum distance (m) for every checked pair.
    #[serde(default = "default_margin")]
    pub margin: f64,
    /// Distances above margin + band count as margin + band (m): the broad phase skips those pairs exactly.
    #[serde(default = "default_band")]
    pub band: f64,
    /// Self-collision between the robot's bodies.
    #[serde(default = "yes", rename = "self")]
    pub self_collision: bool,
    /// The mounting plane z = 0 of the base frame for every body but the base.
    #[serde(default = "yes")]
    pub floor: bool,
    /// Obstacles of the cell.
    #[serde(default)]
    pub obstacle: Vec<ObstacleSpec>,
    /// Tool or payload shapes on robot frames.
    #[serde(default)]
    pub attached: Vec<AttachedSpec>,
    /// True when the design file writes a `[collision]` section (set when
    /// the section is read; false for the default of a design without one):
    /// such a design asks for collision checks, and a robot without
    /// collision geometry is then an error instead of `collisions NOT checked`.
    #[serde(skip_serializing, skip_deserializing, default = "yes")]
    pub requested: bool,
}

impl Default for CollisionSpec {
    fn default() -> Self {
        CollisionSpec {
            enabled: true,
            margin: default_margin(),
            band: default_band(),
            self_collision: true,
            floor: true,
            obstacle: Vec::new(),
            attached: Vec::new(),
            requested: false,
        }
    }
}
