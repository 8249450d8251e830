//! The viewer's state machine: input in, camera and settings out, with no window.
//!
//! [`ViewerState::apply`] takes one frame's [`Input`] (keys pressed, keys held, mouse
//! motion while dragging, seconds since the last frame) and updates the camera [`Pose`] and
//! the settings: the primary method (a `trace::Registry` name), the shadows
//! ([`ShadowMode`]) and the cost overlay. It reports whether the picture must be traced
//! anew ([`Change`]), which is what restarts the progressive refinement of soft shadows.

use glam::Vec3;
use scenes::{Camera, Scene};
use trace::aov::Cost;

/// Where the camera is and where it looks: an eye and two angles (no roll; up is +Y, the
/// camera convention of `scenes::Camera`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Eye position.
    pub eye: Vec3,
    /// Rotation about +Y in radians; 0 looks along -Z.
    pub yaw: f32,
    /// Elevation in radians, kept inside +-[`MAX_PITCH`].
    pub pitch: f32,
}

/// The largest elevation: the camera never looks straight up or down (where `look_at` has no
/// answer).
pub const MAX_PITCH: f32 = 1.5;

impl Pose {
    /// The pose at `eye` looking at `target` (`None` if they coincide or are not finite).
    pub fn look_at(eye: Vec3, target: Vec3) -> Option<Pose> {
        let d = (target - eye).try_normalize()?;
        if !eye.is_finite() {
            return None;
        }
        Some(Pose { eye, yaw: d.x.atan2(-d.z), pitch: d.y.clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH) })
    }

    /// The unit view direction.
    pub fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(cp * sy, sp, -cp * cy)
    }

    /// The unit direction to the right, horizontal.
    pub fn right(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        Vec3::new(cy, 0.0, sy)
    }

    /// The camera of this pose for a `width` x `height` image (`None` for an empty image or a
    /// degenerate pose).
    pub fn camera(&self, fovy_deg: f32, width: u32, height: u32) -> Option<Camera> {
        if width == 0 || height == 0 {
            return None;
        }
        Camera::look_at(self.eye, self.eye + self.forward(), fovy_deg, width, height)
    }
}

/// The shadows of the viewer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowMode {
    /// No shadow rays.
    None,
    /// One ray per hit to the point light (the method's hard-shadow pass).
    Hard,
    /// Edge Width Soft Shadows (thesis chapter 5): one edge-width ray per hit to the centre
    /// of the soft shadows' spherical light (`trace::Shadows::EdgeWidth`, over the kd-tree).
    EdgeWidth,
    /// Silhouette widths (`edgewidth::silhouette`): the edge-width variant that draws both
    /// halves of the penumbra and does not leak; one shadow ray per hit to the centre of the
    /// same spherical light, the silhouette edges in its cone, a check ray per claimed exit.
    Silhouette,
    /// Convolved edge widths (`edgewidth::convolution`): at most one shadow ray per hit to the
    /// centre of the same spherical light (every other pixel of every other row, and between
    /// them where those disagree), and the hard shadow averaged over the light's image
    /// through the nearest blocker near its edges; no search.
    Convolution,
    /// 16 rays per hit to a spherical light (the method's soft-shadow pass), refined with 16
    /// more per hit each frame while the camera rests.
    Soft,
}

impl ShadowMode {
    /// Every mode, in the order of the `H` key.
    pub const ALL: [ShadowMode; 6] = [
        ShadowMode::None,
        ShadowMode::Hard,
        ShadowMode::EdgeWidth,
        ShadowMode::Silhouette,
        ShadowMode::Convolution,
        ShadowMode::Soft,
    ];

    /// The mode called `name` (its [`ShadowMode::name`]).
    pub fn from_name(name: &str) -> Option<ShadowMode> {
        ShadowMode::ALL.into_iter().find(|m| m.name() == name)
    }

    /// The next mode (`H` key): none, hard, edge width, silhouette widths, convolved edge
    /// widths, soft, none.
    pub fn next(self) -> ShadowMode {
        match self {
            ShadowMode::None => ShadowMode::Hard,
            ShadowMode::Hard => ShadowMode::EdgeWidth,
            ShadowMode::EdgeWidth => ShadowMode::Silhouette,
            ShadowMode::Silhouette => ShadowMode::Convolution,
            ShadowMode::Convolution => ShadowMode::Soft,
            ShadowMode::Soft => ShadowMode::None,
        }
    }

    /// Its name on the status line.
    pub fn name(self) -> &'static str {
        match self {
            ShadowMode::None => "none",
            ShadowMode::Hard => "hard",
            ShadowMode::EdgeWidth => "edge-width",
            ShadowMode::Silhouette => "edge-width-silhouette",
            ShadowMode::Convolution => "edge-width-convolution",
            ShadowMode::Soft => "soft",
        }
    }
}

/// What a key does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Move forward (W, held).
    Forward,
    /// Move back (S, held).
    Back,
    /// Move left (A, held).
    Left,
    /// Move right (D, held).
    Right,
    /// Move up (E, held).
    Up,
    /// Move down (Q, held).
    Down,
    /// Next primary method (M).
    NextMethod,
    /// Previous primary method (N).
    PrevMethod,
    /// Next shadow mode (H).
    NextShadows,
    /// Secondary rays on or off (R): one generation of reflections and refractions from
    /// the reflective and transparent materials (`trace::secondary`).
    ToggleSecondary,
    /// Next cost overlay: none, nodes, leaves, isects, culled (C).
    NextOverlay,
    /// Lock or unlock the cost overlay's colour scale (L): locked, it is kept whatever the
    /// method, overlay or view, to compare them on one scale.
    LockScale,
    /// The scene's named view `i` (number key `i + 1`).
    View(usize),
}

/// One frame's input.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Input {
    /// Keys pressed since the last frame (each acts once).
    pub pressed: Vec<Action>,
    /// Movement keys held down.
    pub held: Vec<Action>,
    /// Mouse motion in pixels while the button is down (turns the camera).
    pub drag: (f32, f32),
    /// Seconds since the last frame (movement is speed times this).
    pub dt: f32,
}

/// What changed in one [`ViewerState::apply`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Change {
    /// The camera moved or turned.
    pub camera: bool,
    /// The method, shadows or overlay changed.
    pub settings: bool,
}

impl Change {
    /// Whether the picture must be traced anew.
    pub fn any(self) -> bool {
        self.camera || self.settings
    }
}

/// Radians per pixel of mouse drag.
pub const TURN_PER_PIXEL: f32 = 0.004;

/// The viewer's state.
#[derive(Clone, Debug)]
pub struct ViewerState {
    /// The camera.
    pub pose: Pose,
    /// Vertical field of view in degrees.
    pub fovy_deg: f32,
    /// The primary methods to switch between: `trace::Registry` names.
    pub methods: Vec<String>,
    /// The current one, an index into `methods`.
    pub method: usize,
    /// The shadows.
    pub shadows: ShadowMode,
    /// Whether frames trace one generation of secondary rays ([`Action::ToggleSecondary`]).
    pub secondary: bool,
    /// The cost overlay, if any.
    pub overlay: Option<Cost>,
    /// Whether the overlay's colour scale is locked ([`Action::LockScale`]). Unlocked, the
    /// scale is the first overlay frame's maximum after the method, the overlay or the named
    /// view changes, and stays while the camera moves (values above it saturate).
    pub scale_locked: bool,
    /// How many times a named view was chosen (a number key): a new named view gets a new
    /// overlay scale.
    pub view_jumps: u32,
    /// The scene's named views: (name, pose, field of view).
    pub views: Vec<(String, Pose, f32)>,
    /// Movement speed in scene units per second.
    pub speed: f32,
}

impl ViewerState {
    /// The state at `scene`'s default view, switching between `methods` (starting at
    /// `method`), moving a quarter of the scene's diagonal per second.
    pub fn new(scene: &Scene, methods: Vec<String>, method: usize) -> ViewerState {
        let views: Vec<(String, Pose, f32)> = scene
            .views
            .iter()
            .filter_map(|v| Some((v.name.clone(), Pose::look_at(v.eye, v.target)?, v.fovy_deg)))
            .collect();
        let (pose, fovy_deg) = views
            .first()
            .map(|v| (v.1, v.2))
            .unwrap_or((Pose { eye: Vec3::new(0.0, 0.0, 5.0), yaw: 0.0, pitch: 0.0 }, 60.0));
        let diag = scene.mesh.bounds().map_or(1.0, |(lo, hi)| (hi - lo).length());
        let method = method.min(methods.len().saturating_sub(1));
        ViewerState {
            pose,
            fovy_deg,
            methods,
            method,
            shadows: ShadowMode::Hard,
            secondary: false,
            overlay: None,
            scale_locked: false,
            view_jumps: 0,
            views,
            speed: 0.25 * diag,
        }
    }

    /// The current method's name.
    pub fn method_name(&self) -> &str {
        self.methods.get(self.method).map_or("", String::as_str)
    }

    /// Applies one frame's input.
    pub fn apply(&mut self, input: &Input) -> Change {
        let mut change = Change::default();
        let n = self.methods.len().max(1);
        for &action in &input.pressed {
            match action {
                Action::NextMethod => self.method = (self.method + 1) % n,
                Action::PrevMethod => self.method = (self.method + n - 1) % n,
                Action::NextShadows => self.shadows = self.shadows.next(),
                Action::ToggleSecondary => self.secondary = !self.secondary,
                Action::LockScale => self.scale_locked = !self.scale_locked,
                Action::NextOverlay => {
                    self.overlay = match self.overlay {
                        None => Some(Cost::ALL[0]),
                        Some(c) => Cost::ALL.iter().position(|&x| x == c).and_then(|i| Cost::ALL.get(i + 1)).copied(),
                    }
                }
                Action::View(i) => {
                    if let Some(&(_, pose, fovy)) = self.views.get(i) {
                        self.pose = pose;
                        self.fovy_deg = fovy;
                        self.view_jumps = self.view_jumps.wrapping_add(1);
                        change.camera = true;
                    }
                    continue;
                }
                _ => continue,
            }
            change.settings = true;
        }
        let dt = if input.dt.is_finite() { input.dt.clamp(0.0, 0.25) } else { 0.0 };
        let mut step = Vec3::ZERO;
        for &action in &input.held {
            step += match action {
                Action::Forward => self.pose.forward(),
                Action::Back => -self.pose.forward(),
                Action::Right => self.pose.right(),
                Action::Left => -self.pose.right(),
                Action::Up => Vec3::Y,
                Action::Down => -Vec3::Y,
                _ => Vec3::ZERO,
            };
        }
        if step != Vec3::ZERO && dt > 0.0 {
            self.pose.eye += step.normalize_or_zero() * self.speed * dt;
            change.camera = true;
        }
        let (dx, dy) = input.drag;
        if (dx != 0.0 || dy != 0.0) && dx.is_finite() && dy.is_finite() {
            self.pose.yaw += dx * TURN_PER_PIXEL;
            self.pose.pitch = (self.pose.pitch - dy * TURN_PER_PIXEL).clamp(-MAX_PITCH, MAX_PITCH);
            change.camera = true;
        }
        change
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> ViewerState {
        let scene = scenes::load_scene("atrium").unwrap();
        ViewerState::new(&scene, vec!["mono".into(), "mft-16".into()], 1)
    }

    #[test]
    fn pose_round_trips_a_view() {
        let pose = Pose::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 1.0, -2.0)).unwrap();
        let d = (Vec3::new(3.0, -1.0, -5.0)).normalize();
        assert!((pose.forward() - d).length() < 1e-5, "{:?}", pose.forward());
        assert!(pose.right().dot(pose.forward()).abs() < 1e-5);
        assert!(Pose::look_at(Vec3::ONE, Vec3::ONE).is_none());
        assert!(pose.camera(60.0, 0, 10).is_none(), "a minimised window has no camera");
        assert!(pose.camera(60.0, 64, 48).is_some());
    }

    #[test]
    fn keys_switch_method_shadows_and_overlay() {
        let mut s = state();
        assert_eq!(s.method_name(), "mft-16");
        let press = |a| Input { pressed: vec![a], ..Input::default() };
        assert!(s.apply(&press(Action::NextMethod)).settings);
        assert_eq!(s.method_name(), "mono");
        s.apply(&press(Action::PrevMethod));
        assert_eq!(s.method_name(), "mft-16");
        assert_eq!(s.shadows, ShadowMode::Hard);
        assert!(!s.secondary);
        assert!(s.apply(&press(Action::ToggleSecondary)).settings && s.secondary);
        assert!(s.apply(&press(Action::ToggleSecondary)).settings && !s.secondary);
        let mut cycle = Vec::new();
        for _ in 0..6 {
            assert!(s.apply(&press(Action::NextShadows)).settings);
            cycle.push(s.shadows);
        }
        assert_eq!(
            cycle,
            [
                ShadowMode::EdgeWidth,
                ShadowMode::Silhouette,
                ShadowMode::Convolution,
                ShadowMode::Soft,
                ShadowMode::None,
                ShadowMode::Hard
            ]
        );
        for m in ShadowMode::ALL {
            assert_eq!(ShadowMode::from_name(m.name()), Some(m));
            assert_eq!(ShadowMode::ALL[(ShadowMode::ALL.iter().position(|&x| x == m).unwrap() + 1) % 6], m.next());
        }
        assert_eq!(ShadowMode::from_name("soft16"), None);
        for _ in 0..4 {
            s.apply(&press(Action::NextShadows));
        }
        assert_eq!(s.shadows, ShadowMode::Soft);
        let mut seen = Vec::new();
        for _ in 0..5 {
            s.apply(&press(Action::NextOverlay));
            seen.push(s.overlay);
        }
        assert_eq!(seen, [Some(Cost::Nodes), Some(Cost::Leaves), Some(Cost::Isects), Some(Cost::Culled), None]);
        assert!(!s.scale_locked);
        assert!(s.apply(&press(Action::LockScale)).settings);
        assert!(s.scale_locked);
        s.apply(&press(Action::LockScale));
        assert!(!s.scale_locked);
        assert_eq!(s.apply(&Input::default()), Change::default(), "no input, no change");
    }

    #[test]
    fn wasd_moves_and_the_mouse_turns() {
        let mut s = state();
        let start = s.pose;
        let c = s.apply(&Input { held: vec![Action::Forward], dt: 0.1, ..Input::default() });
        assert!(c.camera && !c.settings);
        let moved = s.pose.eye - start.eye;
        assert!((moved.normalize() - start.forward()).length() < 1e-4);
        assert!((moved.length() - s.speed * 0.1).abs() < 1e-3 * s.speed);
        s.apply(&Input { held: vec![Action::Left, Action::Right], dt: 0.1, ..Input::default() });
        assert!((s.pose.eye - start.eye - moved).length() < 1e-4, "opposite keys cancel");
        s.apply(&Input { drag: (100.0, -1e6), ..Input::default() });
        assert!((s.pose.yaw - start.yaw - 0.4).abs() < 1e-5 && s.pose.pitch == MAX_PITCH);
        assert!(s.pose.camera(s.fovy_deg, 32, 32).is_some(), "clamped pitch keeps a camera");
        s.apply(&Input { drag: (f32::NAN, 1.0), held: vec![Action::Forward], dt: f32::INFINITY, ..Input::default() });
        assert!(s.pose.eye.is_finite() && s.pose.yaw.is_finite());
    }

    #[test]
    fn number_keys_go_to_named_views() {
        let mut s = state();
        assert!(s.views.len() >= 2, "atrium has several views");
        let c = s.apply(&Input { pressed: vec![Action::View(1)], ..Input::default() });
        assert!(c.camera);
        assert_eq!(s.pose, s.views[1].1);
        assert_eq!(s.view_jumps, 1);
        assert_eq!(s.apply(&Input { pressed: vec![Action::View(99)], ..Input::default() }), Change::default());
    }
}
