//! The pinhole camera and the one ray convention of the workspace.

use glam::{Vec3, Vec4};

/// Pixels per piece when a row is cut into pieces for [`Camera::lane_directions`] (two groups
/// of its four lanes).
pub const ROW_LANES: usize = 8;

/// The lanes' square roots (correctly rounded, as `f32::sqrt`).
#[inline(always)]
fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: SSE is part of every x86-64 CPU (the target's baseline features).
        Vec4::from(unsafe { std::arch::x86_64::_mm_sqrt_ps(v.into()) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec4::from_array(v.to_array().map(f32::sqrt))
    }
}

/// A pinhole camera with a look-at frame.
///
/// The convention, fixed so that any other tracer can reproduce our rays exactly:
/// - eye `e` looks at target `t`, world up is +Y;
/// - `fovy_deg` is the full vertical field of view in degrees, aspect = width / height;
/// - the ray of pixel `(x, y)` passes through the pixel centre `(x + 0.5, y + 0.5)`;
/// - row `y = 0` is the top of the image;
/// - directions are normalised, so a hit distance `t` is a Euclidean distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (every primary ray starts here).
    pub eye: Vec3,
    /// Unit view direction (from eye towards target).
    pub forward: Vec3,
    /// Unit camera right vector (`forward x up`, normalised).
    pub right: Vec3,
    /// Unit camera up vector (`right x forward`).
    pub up: Vec3,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// `tan(fovy / 2)`: half the image plane height at distance 1.
    pub tan_half_fovy: f32,
}

impl Camera {
    /// A camera at `eye` looking at `target` with vertical field of view `fovy_deg` (degrees)
    /// for a `width` x `height` image.
    ///
    /// Returns `None` if the frame is degenerate: eye equal to target, a view direction
    /// parallel to +Y, non-finite input, a zero image size, or a field of view outside
    /// (0, 180) degrees.
    pub fn look_at(eye: Vec3, target: Vec3, fovy_deg: f32, width: u32, height: u32) -> Option<Camera> {
        if !eye.is_finite() || !target.is_finite() || !fovy_deg.is_finite() {
            return None;
        }
        if width == 0 || height == 0 || fovy_deg <= 0.0 || fovy_deg >= 180.0 {
            return None;
        }
        let forward = (target - eye).try_normalize()?;
        let right = forward.cross(Vec3::Y).try_normalize()?;
        let up = right.cross(forward);
        Some(Camera { eye, forward, right, up, width, height, tan_half_fovy: (fovy_deg.to_radians() * 0.5).tan() })
    }

    /// The normalised direction of the ray through image position `(px, py)`, in pixels
    /// from the top-left corner of the image (pixel centres are at `x + 0.5`). A NaN or
    /// infinite position gives a NaN direction (never a panic).
    #[inline]
    pub fn direction(&self, px: f32, py: f32) -> Vec3 {
        let aspect = self.width as f32 / self.height as f32;
        let sx = (2.0 * px / self.width as f32 - 1.0) * self.tan_half_fovy * aspect;
        let sy = (1.0 - 2.0 * py / self.height as f32) * self.tan_half_fovy;
        (self.forward + sx * self.right + sy * self.up).normalize()
    }

    /// Origin and normalised direction of the primary ray of pixel `(x, y)`, through the
    /// pixel centre.
    #[inline]
    pub fn pixel_ray(&self, x: u32, y: u32) -> (Vec3, Vec3) {
        (self.eye, self.direction(x as f32 + 0.5, y as f32 + 0.5))
    }

    /// The directions of the primary rays of pixels `x0..x0 + 4` of row `y` in SIMD lanes,
    /// `[x, y, z]` (lane `l` is pixel `x0 + l`): [`Camera::pixel_ray`]'s bit for bit. They
    /// are made in `Vec4` lanes, each operation the one `direction` does in its order (every
    /// lane operation, square root included, is rounded as the scalar one is), so the
    /// divisions and square roots share SIMD instructions: per pixel they are the longest
    /// chain of the shadow rays' setup (`trace::method::ShadowJob::row_segments`).
    #[inline(always)]
    pub fn lane_directions(&self, x0: u32, y: u32) -> [Vec4; 3] {
        let (w, h) = (self.width as f32, self.height as f32);
        let aspect = w / h;
        let sy = (1.0 - 2.0 * (y as f32 + 0.5) / h) * self.tan_half_fovy;
        let (f, r, u) = (self.forward, self.right, self.up);
        let (two, one) = (Vec4::splat(2.0), Vec4::ONE);
        let px = Vec4::from_array(std::array::from_fn(|l| x0.wrapping_add(l as u32) as f32 + 0.5));
        let sx = (two * px / Vec4::splat(w) - one) * self.tan_half_fovy * aspect;
        // `forward + sx * right + sy * up`, component by component.
        let vx = Vec4::splat(f.x) + sx * r.x + Vec4::splat(sy * u.x);
        let vy = Vec4::splat(f.y) + sx * r.y + Vec4::splat(sy * u.y);
        let vz = Vec4::splat(f.z) + sx * r.z + Vec4::splat(sy * u.z);
        // `normalize`: times `1 / sqrt(v . v)`, the dot product summed from `x`.
        let inv = one / sqrt4(vx * vx + vy * vy + vz * vz);
        [vx * inv, vy * inv, vz * inv]
    }

    /// How many world units a pixel covers across at `point`'s distance from the eye (the
    /// image plane's height at that distance over the pixel rows): the screen-space
    /// techniques' unit (the edge widths' penumbra reach, `edgewidth::sparse`). NaN for a
    /// non-finite point.
    #[inline]
    pub fn footprint(&self, point: Vec3) -> f32 {
        2.0 * self.tan_half_fovy / self.height as f32 * point.distance(self.eye)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn a_pixel_covers_the_image_plane_over_the_rows() {
        let c = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), 90.0, 200, 100).unwrap();
        // At distance 10 the image plane is 20 high: 0.2 per row, whatever the direction.
        assert_relative_eq!(c.footprint(Vec3::new(0.0, 0.0, -10.0)), 0.2, epsilon = 1e-6);
        assert_relative_eq!(c.footprint(Vec3::new(6.0, 0.0, 8.0)), 0.2, epsilon = 1e-6);
        assert_eq!(c.footprint(c.eye), 0.0);
        assert!(c.footprint(Vec3::NAN).is_nan());
    }

    /// The lanes' directions are `pixel_ray`'s bit for bit: four pixels from any start in a
    /// row (past its end too), odd and even sizes, wide and narrow fields of view, a camera far
    /// from the origin.
    #[test]
    fn lane_directions_are_pixel_rays_bit_for_bit() {
        let cams = [
            (Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 2.5, -1.0), 60.0, 37, 23),
            (Vec3::new(-1e5, 3e4, 2e5), Vec3::new(-1e5 + 3.0, 3e4 - 1.0, 2e5 + 0.5), 1.0, 1024, 768),
            (Vec3::ZERO, Vec3::new(0.3, -0.2, -1.0), 170.0, 16, 16),
        ];
        for (eye, target, fov, w, h) in cams {
            let cam = Camera::look_at(eye, target, fov, w, h).unwrap();
            for y in [0, h / 2, h - 1] {
                for x0 in [0, 3, 5, w - 4, w - 1, w / 2] {
                    let lanes = cam.lane_directions(x0, y).map(|v| v.to_array());
                    for (l, x) in (x0..x0 + 4).enumerate() {
                        let got = Vec3::new(lanes[0][l], lanes[1][l], lanes[2][l]);
                        let want = cam.pixel_ray(x, y).1;
                        assert_eq!(got.to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "{x},{y}");
                    }
                }
            }
        }
    }

    #[test]
    fn centre_ray_points_at_target_for_odd_sizes() {
        let cam = Camera::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 2.0, -1.0), 60.0, 5, 3).unwrap();
        let (o, d) = cam.pixel_ray(2, 1);
        assert_eq!(o, cam.eye);
        assert_relative_eq!(d.dot(cam.forward), 1.0, epsilon = 1e-6);
    }

    #[test]
    fn top_row_looks_up_and_corners_span_the_fov() {
        let cam = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), 90.0, 4, 4).unwrap();
        let top = cam.direction(2.0, 0.0);
        assert!(top.y > 0.0);
        // The top edge of the image is at 45 degrees for a 90 degree vertical fov.
        assert_relative_eq!(top.y / -top.z, 1.0, epsilon = 1e-6);
        let left = cam.direction(0.0, 2.0);
        assert!(left.x < 0.0);
    }

    #[test]
    fn degenerate_frames_are_rejected() {
        assert!(Camera::look_at(Vec3::ZERO, Vec3::ZERO, 60.0, 4, 4).is_none());
        assert!(Camera::look_at(Vec3::ZERO, Vec3::Y, 60.0, 4, 4).is_none());
        assert!(Camera::look_at(Vec3::ZERO, Vec3::X, 60.0, 0, 4).is_none());
    }

    #[test]
    fn non_finite_input_gives_no_camera() {
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        for (eye, target, fovy) in [
            (Vec3::new(nan, 0.0, 0.0), Vec3::X, 60.0),
            (Vec3::new(0.0, 0.0, -inf), Vec3::X, 60.0),
            (Vec3::ZERO, Vec3::new(1.0, nan, 0.0), 60.0),
            (Vec3::ZERO, Vec3::new(inf, 0.0, 0.0), 60.0),
            (Vec3::ZERO, Vec3::X, nan),
            (Vec3::ZERO, Vec3::X, inf),
            (Vec3::ZERO, Vec3::X, -inf),
            // Finite, but so far apart that the view vector overflows.
            (Vec3::new(-3e38, 0.0, 0.0), Vec3::new(3e38, 0.0, 0.0), 60.0),
        ] {
            assert!(Camera::look_at(eye, target, fovy, 4, 4).is_none(), "{eye} {target} {fovy}");
        }
        let cam = Camera::look_at(Vec3::ZERO, Vec3::X, 60.0, 4, 4).unwrap();
        assert!(cam.direction(nan, 1.0).is_nan() && cam.direction(1.0, inf).is_nan());
    }
}
