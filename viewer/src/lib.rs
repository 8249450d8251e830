//! The interactive viewer's library: everything but the window, so that it is tested
//! headless.
//!
//! - [`state`]: the state machine: one frame's input (keys pressed and held, mouse drag,
//!   elapsed time) moves the camera and switches the primary method (a `trace::Registry`
//!   name), the shadows (none, hard, edge width, silhouette widths, convolved edge widths, soft) and the cost overlay (`trace::aov`).
//! - [`frame_loop`]: a state and a size to a framebuffer with a status line (fps, Mrays/s,
//!   method, threads, N and I per packet), through `trace::Renderer`; soft shadows refine
//!   while the camera rests.
//! - [`refine`]: the jittered light samples of the refinement passes.
//!
//! The binary (`src/main.rs`) adds the window (minifb, X11) and traces on a thread of its
//! own, so the window stays responsive.

pub mod frame_loop;
pub mod refine;
pub mod state;

pub use frame_loop::{FrameInfo, FrameLoop, RoundTimes};
pub use state::{Action, Change, Input, Pose, ShadowMode, ViewerState};
