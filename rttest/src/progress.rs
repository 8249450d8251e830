//! Progress bars on stderr that only appear for work taking more than a second.
//!
//! A [`Bar`] starts hidden. A watcher thread waits one second; if the work is still
//! running then (and progress display is enabled: stderr is a terminal and `--json` is off)
//! the bar is drawn until [`Bar::finish`] clears it. Quick work therefore never flickers
//! a bar. A spinner ticks on its own (a long single call such as a big build still moves); a
//! bar is redrawn only when it advances, so no drawing thread competes with timed work.

use std::io::IsTerminal;
use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::thread::JoinHandle;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How long work runs before its bar appears.
pub const SHOW_AFTER: Duration = Duration::from_secs(1);

/// Whether progress may be drawn: stderr is a terminal and the output is not JSON.
pub fn enabled(json: bool) -> bool {
    !json && std::io::stderr().is_terminal()
}

/// A progress bar or spinner that appears after [`SHOW_AFTER`]; see the module docs.
#[derive(Debug)]
pub struct Bar {
    bar: ProgressBar,
    done: Option<Sender<()>>,
    watcher: Option<JoinHandle<()>>,
}

impl Bar {
    /// A spinner with `message`, for work without measurable steps (loading, building).
    pub fn spinner(message: &str, enabled: bool) -> Bar {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        Self::start(bar, message, enabled, true)
    }

    /// A bar of `len` steps with `message` (frames, for example).
    pub fn steps(len: u64, message: &str, enabled: bool) -> Bar {
        let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Self::start(bar, message, enabled, false)
    }

    fn start(bar: ProgressBar, message: &str, enabled: bool, ticking: bool) -> Bar {
        bar.set_message(message.to_string());
        if !enabled {
            return Bar { bar, done: None, watcher: None };
        }
        let (done, rx) = mpsc::channel::<()>();
        let shown = bar.clone();
        let watcher = std::thread::spawn(move || {
            if let Err(RecvTimeoutError::Timeout) = rx.recv_timeout(SHOW_AFTER) {
                shown.set_draw_target(ProgressDrawTarget::stderr());
                if ticking {
                    shown.enable_steady_tick(Duration::from_millis(120));
                } else {
                    shown.tick();
                }
            }
        });
        Bar { bar, done: Some(done), watcher: Some(watcher) }
    }

    /// One step done.
    pub fn inc(&self) {
        self.bar.inc(1);
    }

    /// The work is done: the bar, if shown, is cleared.
    pub fn finish(mut self) {
        self.stop();
    }

    fn stop(&mut self) {
        if let Some(done) = self.done.take() {
            let _ = done.send(());
        }
        if let Some(watcher) = self.watcher.take() {
            let _ = watcher.join();
        }
        self.bar.finish_and_clear();
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.stop();
    }
}

impl trace::progress::Task for Bar {
    fn inc(&self) {
        Bar::inc(self);
    }

    fn finish(self: Box<Self>) {
        Bar::finish(*self);
    }
}

/// The command line's [`trace::progress::Progress`]: bars on stderr when `enabled` (stderr is a
/// terminal and the output is not JSON; see [`enabled`]), nothing otherwise.
#[derive(Clone, Copy, Debug)]
pub struct Bars {
    /// Whether bars may be drawn.
    pub enabled: bool,
}

impl trace::progress::Progress for Bars {
    fn task(&self, message: &str, len: Option<u64>) -> Box<dyn trace::progress::Task> {
        Box::new(match len {
            Some(len) => Bar::steps(len, message, self.enabled),
            None => Bar::spinner(message, self.enabled),
        })
    }
}
