//! Light sources: a point light (hard shadows) and two area lights (soft shadows).
//!
//! Plain data, not checked here: the methods compute with whatever they hold (NaN in, NaN
//! out, never a panic), and the tracers that sample lights say what a non-finite light gets
//! (`cones::shadows::light_samples`: no samples; `edgewidth::sampling`: its samples count as
//! blocked).

use glam::Vec3;

/// A point light with inverse-square attenuation, the thesis's benchmark light (4.1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position in world space.
    pub position: Vec3,
    /// Radiant intensity per colour channel.
    pub intensity: Vec3,
}

/// A rectangular (parallelogram) area light: `corner + s * edge_u + t * edge_v`, `s, t` in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RectLight {
    /// One corner of the rectangle.
    pub corner: Vec3,
    /// First edge vector.
    pub edge_u: Vec3,
    /// Second edge vector.
    pub edge_v: Vec3,
    /// Emitted intensity per colour channel (as if concentrated at the centre).
    pub intensity: Vec3,
}

impl RectLight {
    /// The centre of the rectangle.
    pub fn center(&self) -> Vec3 {
        self.corner + 0.5 * (self.edge_u + self.edge_v)
    }

    /// The point at parameters `(s, t)` in `[0, 1]^2`.
    pub fn point(&self, s: f32, t: f32) -> Vec3 {
        self.corner + s * self.edge_u + t * self.edge_v
    }
}

/// A spherical area light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereLight {
    /// Centre of the sphere.
    pub center: Vec3,
    /// Radius of the sphere.
    pub radius: f32,
    /// Emitted intensity per colour channel (as if concentrated at the centre).
    pub intensity: Vec3,
}
