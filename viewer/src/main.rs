//! `viewer`: a window with a scene traced live.
//!
//! Keys: W/A/S/D move, Q/E down/up, drag with the left mouse button to turn; 1-9 the
//! scene's named views; M/N next/previous method (every `trace::Registry` method, tiled ones
//! with 16x16 tiles); H shadows (none, hard, edge width, silhouette widths, convolved edge widths, soft: refined while the camera
//! rests); R secondary rays on or off (reflections and refractions; not in the progressive soft
//! mode); C cost overlay (none, nodes, leaves, isects, culled per ray; its scale is fixed
//! per method, overlay and named view); L locks the overlay's scale; Escape quits.
//!
//! The window and its events live on the main thread; frames are traced on a render thread
//! (with rayon's pool), which gets the latest state whenever it is free, so the window stays
//! responsive whatever a frame costs. A minimised (zero-sized) window traces nothing.

use std::io::Write;
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use clap::Parser;
use kdtree::KdTree;
use minifb::{Key, KeyRepeat, MouseButton, MouseMode, ScaleMode, Window, WindowOptions};
use viewer::{Action, Change, FrameInfo, FrameLoop, Input, ShadowMode, ViewerState};

/// An interactive viewer: a scene traced live with any registered method.
#[derive(Debug, Parser)]
#[command(name = "viewer", version)]
struct Args {
    /// A built-in scene or an .obj / .obj.gz file.
    #[arg(long, default_value = "atrium", value_name = "NAME|PATH")]
    scene: String,
    /// Window size.
    #[arg(long, default_value = "1024x768", value_name = "WxH", value_parser = parse_size)]
    size: (u32, u32),
    /// The first method (a registry name; M and N switch).
    #[arg(long, default_value = "mft-16", value_name = "METHOD")]
    method: String,
    /// The first shadow mode (H switches): none, hard, edge-width, edge-width-silhouette,
    /// edge-width-convolution or soft.
    #[arg(long, default_value = "hard", value_name = "MODE", value_parser = parse_shadows)]
    shadows: ShadowMode,
    /// Rayon threads (default: all cores).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Render the first frame without a window into this PNG and exit.
    #[arg(long, value_name = "FILE")]
    headless: Option<PathBuf>,
    /// With --headless: trace this many frames of a moving camera first (nothing counted) and
    /// print the best and the median frame time, fps and Mrays/s.
    #[arg(long, default_value_t = 0, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=10000))]
    frames: u32,
    /// With --headless and --frames N: N interleaved rounds of the viewer's frame and of what
    /// `rttest render` times for the same frame (`Renderer::trace` and `Renderer::color`),
    /// in one process, and their medians and ratio.
    #[arg(long, requires = "headless")]
    against_render: bool,
    /// Close the window after this many seconds (for scripted runs).
    #[arg(long, value_name = "SECS")]
    exit_after: Option<f64>,
}

/// A shadow mode by its name.
fn parse_shadows(s: &str) -> Result<ShadowMode, String> {
    ShadowMode::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = ShadowMode::ALL.iter().map(|m| m.name()).collect();
        format!("'{s}' is not one of {}", names.join(", "))
    })
}

/// `WxH`, each side in 1..=8192.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("expected WxH, got '{s}'"))?;
    let side = |v: &str| v.trim().parse::<u32>().ok().filter(|n| (1..=8192).contains(n));
    Ok((side(w).ok_or(format!("bad width '{w}'"))?, side(h).ok_or(format!("bad height '{h}'"))?))
}

/// A frame request to the render thread.
struct Job {
    state: ViewerState,
    change: Change,
    width: u32,
    height: u32,
}

/// The render thread's answer: a frame, or nothing new.
type Done = Result<Option<(Vec<u32>, u32, u32, FrameInfo)>, String>;

fn main() {
    let args = Args::parse();
    if let Err(e) = run(&args) {
        eprintln!("viewer: {e}");
        std::process::exit(1);
    }
}

fn run(args: &Args) -> Result<(), String> {
    if let Some(n) = args.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n as usize).build_global().map_err(|e| e.to_string())?;
    }
    if let Some(t) = args.exit_after
        && !(t.is_finite() && t >= 0.0)
    {
        return Err(format!("--exit-after {t} must be a finite number >= 0"));
    }
    let started = Instant::now();
    let scene = scenes::load_scene(&args.scene).map_err(|e| e.to_string())?;
    let tree =
        KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &Default::default()).map_err(|e| e.to_string())?;
    let frames = FrameLoop::new(&scene, &tree);
    let names = frames.method_names();
    let Some(first) = names.iter().position(|n| *n == args.method) else {
        return Err(format!("--method {}: not one of {}", args.method, names.join(", ")));
    };
    let mut state = ViewerState::new(&scene, names, first);
    state.shadows = args.shadows;
    let (width, height) = args.size;
    if let Some(path) = &args.headless {
        let mut frames = frames;
        let mut out = Vec::new();
        if args.against_render && args.frames > 0 {
            let times = frames.time_against_renderer(&state, width, height, args.frames).map_err(|e| e.to_string())?;
            let med = |f: &dyn Fn(&viewer::RoundTimes) -> f64| {
                trace::timing::median(&times.iter().map(f).collect::<Vec<f64>>()) * 1e3
            };
            let (frame, vtrace) = (med(&|t| t.viewer_frame), med(&|t| t.viewer_trace));
            let (rtrace, shade) = (med(&|t| t.render_trace), med(&|t| t.render_shade));
            let both = med(&|t| t.render_trace + t.render_shade);
            let ratio = trace::timing::median(
                &times.iter().map(|t| t.viewer_frame / (t.render_trace + t.render_shade)).collect::<Vec<f64>>(),
            );
            let _ = writeln!(
                std::io::stdout(),
                "{} interleaved rounds of {width}x{height}, {}, shadows {}, {} threads, medians: viewer frame \
                 {frame:.2} ms ({:.2} fps; its tracing {vtrace:.2} ms); rttest render's trace {rtrace:.2} ms \
                 + shade {shade:.2} ms = {both:.2} ms ({:.2} fps); viewer frame / (trace + shade) {ratio:.3} \
                 (median of the rounds' ratios)",
                times.len(),
                state.method_name(),
                state.shadows.name(),
                rayon::current_num_threads(),
                1e3 / frame,
                1e3 / both,
            );
        } else if args.frames > 0 {
            let moving = Change { camera: true, settings: false };
            let mut timed = Vec::new();
            for _ in 0..args.frames {
                let info = frames.render(&state, moving, width, height, &mut out).map_err(|e| e.to_string())?;
                timed.extend(info.map(|i| (i.frame_secs, i.trace_secs, i.rays)));
            }
            timed.sort_by(|a, b| a.0.total_cmp(&b.0));
            let line = |what: &str, (frame, trace, rays): (f64, f64, u64)| {
                format!(
                    "{what} frame {:.2} ms ({:.2} fps), its tracing {:.2} ms ({:.2} Mrays/s)",
                    frame * 1e3,
                    1.0 / frame,
                    trace * 1e3,
                    rays as f64 / trace / 1e6
                )
            };
            if let (Some(&best), Some(&median)) = (timed.first(), timed.get(timed.len() / 2)) {
                let _ = writeln!(
                    std::io::stdout(),
                    "{} frames of {width}x{height}, {}, shadows {}, {} threads: {}; {}",
                    timed.len(),
                    state.method_name(),
                    state.shadows.name(),
                    rayon::current_num_threads(),
                    line("best", best),
                    line("median", median)
                );
            }
        }
        // A camera at rest: N and I are counted.
        let change = Change { camera: false, settings: true };
        let info = frames.render(&state, change, width, height, &mut out).map_err(|e| e.to_string())?;
        let info = info.ok_or("no frame")?;
        let rgb = out.iter().flat_map(|p| [(p >> 16) as u8, (p >> 8) as u8, *p as u8]).collect();
        scenes::Rgb8Image { width, height, rgb }.save_png(path).map_err(|e| e.to_string())?;
        let _ = writeln!(std::io::stdout(), "{}", info.status(&state));
        return Ok(());
    }
    drop(frames);
    let (job_tx, job_rx) = mpsc::channel::<Job>();
    let (done_tx, done_rx) = mpsc::channel::<Done>();
    std::thread::scope(|s| {
        s.spawn(|| render_thread(&scene, &tree, job_rx, done_tx));
        let result = window_loop(args, state, started, &job_tx, &done_rx);
        drop(job_tx);
        result
    })
}

/// Traces the jobs it receives until the window closes.
fn render_thread(scene: &scenes::Scene, tree: &KdTree, jobs: mpsc::Receiver<Job>, done: mpsc::Sender<Done>) {
    let mut frames = FrameLoop::new(scene, tree);
    let mut out = Vec::new();
    while let Ok(job) = jobs.recv() {
        let answer = frames
            .render(&job.state, job.change, job.width, job.height, &mut out)
            .map(|info| info.map(|info| (out.clone(), job.width, job.height, info)))
            .map_err(|e| e.to_string());
        if done.send(answer).is_err() {
            return;
        }
    }
}

/// The keys that act once when pressed.
fn pressed_action(key: Key) -> Option<Action> {
    Some(match key {
        Key::M => Action::NextMethod,
        Key::N => Action::PrevMethod,
        Key::H => Action::NextShadows,
        Key::R => Action::ToggleSecondary,
        Key::C => Action::NextOverlay,
        Key::L => Action::LockScale,
        Key::Key1 => Action::View(0),
        Key::Key2 => Action::View(1),
        Key::Key3 => Action::View(2),
        Key::Key4 => Action::View(3),
        Key::Key5 => Action::View(4),
        Key::Key6 => Action::View(5),
        Key::Key7 => Action::View(6),
        Key::Key8 => Action::View(7),
        Key::Key9 => Action::View(8),
        _ => return None,
    })
}

/// The keys that act while held.
fn held_action(key: Key) -> Option<Action> {
    Some(match key {
        Key::W => Action::Forward,
        Key::S => Action::Back,
        Key::A => Action::Left,
        Key::D => Action::Right,
        Key::E => Action::Up,
        Key::Q => Action::Down,
        _ => return None,
    })
}

/// The window's event loop: input into the state, frames from the render thread onto the
/// screen.
fn window_loop(
    args: &Args,
    mut state: ViewerState,
    started: Instant,
    jobs: &mpsc::Sender<Job>,
    done: &mpsc::Receiver<Done>,
) -> Result<(), String> {
    let (w, h) = args.size;
    let options = WindowOptions { resize: true, scale_mode: ScaleMode::Stretch, ..WindowOptions::default() };
    let mut window = Window::new(&format!("viewer: {}", args.scene), w as usize, h as usize, options)
        .map_err(|e| format!("cannot open a window: {e}"))?;
    window.set_target_fps(120);
    let mut shown: Option<(Vec<u32>, u32, u32)> = None;
    let mut busy = false;
    let mut pending = Change { camera: true, settings: true };
    let mut last = Instant::now();
    let mut mouse: Option<(f32, f32)> = None;
    let mut first_frame = true;
    while window.is_open() && !window.is_key_down(Key::Escape) {
        if args.exit_after.is_some_and(|t| started.elapsed().as_secs_f64() > t) {
            break;
        }
        let now = Instant::now();
        let dt = (now - last).as_secs_f32();
        last = now;
        let pos = window.get_mouse_pos(MouseMode::Pass);
        let drag = match (window.get_mouse_down(MouseButton::Left), mouse, pos) {
            (true, Some((x0, y0)), Some((x, y))) => (x - x0, y - y0),
            _ => (0.0, 0.0),
        };
        mouse = pos;
        let input = Input {
            pressed: window.get_keys_pressed(KeyRepeat::No).into_iter().filter_map(pressed_action).collect(),
            held: window.get_keys().into_iter().filter_map(held_action).collect(),
            drag,
            dt,
        };
        let change = state.apply(&input);
        if change.settings {
            let overlay = state.overlay.map_or("none", |c| c.name());
            let lock = if state.scale_locked { " (scale locked)" } else { "" };
            eprintln!(
                "viewer: method {} shadows {} overlay {overlay}{lock}",
                state.method_name(),
                state.shadows.name()
            );
        }
        pending.camera |= change.camera;
        pending.settings |= change.settings;
        if let Ok(answer) = done.try_recv() {
            busy = false;
            match answer {
                Ok(Some((pixels, fw, fh, info))) => {
                    if first_frame {
                        eprintln!(
                            "viewer: first frame {:.2} s after start: {}",
                            started.elapsed().as_secs_f64(),
                            info.status(&state)
                        );
                        first_frame = false;
                    }
                    shown = Some((pixels, fw, fh));
                }
                Ok(None) => {}
                Err(e) => eprintln!("viewer: {e}"),
            }
        }
        let (ww, wh) = window.get_size();
        if !busy && ww > 0 && wh > 0 {
            let job = Job { state: state.clone(), change: pending, width: ww as u32, height: wh as u32 };
            if jobs.send(job).is_err() {
                return Err("the render thread stopped".into());
            }
            busy = true;
            pending = Change::default();
        }
        let updated = match &shown {
            Some((pixels, fw, fh)) => window.update_with_buffer(pixels, *fw as usize, *fh as usize).is_ok(),
            None => false,
        };
        if !updated {
            window.update();
        }
        if busy && shown.is_none() {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    Ok(())
}
