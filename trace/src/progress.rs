//! How long work reports how far it has got, without the library drawing anything.
//!
//! Experiments take a `&dyn Progress` and open one [`Task`] per phase (builds, rounds,
//! scenes). The command line draws them as progress bars on a terminal; tests, benches and
//! `--json` runs pass [`Quiet`], which draws nothing.

/// A phase of work: advanced step by step, finished when done (or dropped).
pub trait Task {
    /// One step done.
    fn inc(&self);
    /// The phase is over; its display, if any, goes away.
    fn finish(self: Box<Self>);
}

/// Where progress goes.
pub trait Progress: Sync {
    /// A phase of `len` steps (`None`: unknown, a spinner) described by `message`.
    fn task(&self, message: &str, len: Option<u64>) -> Box<dyn Task>;
}

/// Progress that goes nowhere.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quiet;

impl Task for Quiet {
    fn inc(&self) {}
    fn finish(self: Box<Self>) {}
}

impl Progress for Quiet {
    fn task(&self, _message: &str, _len: Option<u64>) -> Box<dyn Task> {
        Box::new(Quiet)
    }
}
