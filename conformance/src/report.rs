//! What a run found: per check and query, the answers compared and how they matched.

use std::collections::BTreeMap;
use std::fmt::Write as _;

#[cfg(doc)]
use crate::plan::Rule;

/// The suffix of keys that are reported but not judged: the streams and oracle rays under
/// [`Rule::Loose`], whose origins on surfaces make another tracer's `t` near 0 differ from
/// ours (self-hits at `t` ~ 1e-6 against 0 or a far hit).
pub const REPORTED: &str = "(reported, not judged)";

/// Answers compared and how they matched, per check and query.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tally {
    /// Answers compared (rays, pixels).
    pub compared: u64,
    /// Different triangles at the same distance ([`Rule::Loose`]: other hits within 1e-4 of
    /// the distance, the same triangle included).
    pub ties: u64,
    /// Differences the oracle accepts ([`Rule::Equivalent`]).
    pub artefacts: u64,
    /// Differences counted under [`Rule::Loose`].
    pub loose: u64,
    /// Differences the rule refuses.
    pub failures: u64,
}

/// What [`run`](crate::run()) found.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Per `"method (options) vs reference: query"`.
    pub tallies: BTreeMap<String, Tally>,
    /// The first refused answers, described (at most 8 per key).
    pub messages: Vec<String>,
    /// (case, intersector, camera) combinations traced.
    pub views: u64,
    /// Loose disagreements described (at most 8 per key), for the report.
    pub loose_examples: Vec<String>,
    pub(crate) loose_per_10k: f64,
}

impl Report {
    /// The keys whose tallies fail: refused answers, or loose disagreements above the plan's
    /// fraction.
    pub fn failing(&self) -> Vec<String> {
        self.tallies
            .iter()
            .filter(|(k, t)| {
                t.failures > 0
                    || !k.ends_with(REPORTED) && t.loose as f64 * 10_000.0 > self.loose_per_10k * t.compared as f64
            })
            .map(|(k, t)| format!("{k}: {t:?}"))
            .collect()
    }

    /// A summary line per key with any difference.
    pub fn summary(&self) -> String {
        let mut s = format!("{} views, {} keys\n", self.views, self.tallies.len());
        for (k, t) in self.tallies.iter().filter(|(_, t)| t.ties + t.artefacts + t.loose + t.failures > 0) {
            let _ = writeln!(s, "{k}: {t:?}");
        }
        s
    }

    /// Panics naming the failing keys and the first refused answers.
    pub fn assert_ok(&self) {
        let failing = self.failing();
        assert!(
            failing.is_empty(),
            "{} failing:\n{}\nfirst refused answers:\n{}\nloose:\n{}",
            failing.len(),
            failing.join("\n"),
            self.messages.join("\n"),
            self.loose_examples.join("\n")
        );
    }

    /// Records one comparison's outcome.
    pub(crate) fn record(&mut self, key: &str, outcome: Outcome, what: impl FnOnce() -> String) {
        if !self.tallies.contains_key(key) {
            self.tallies.insert(key.to_string(), Tally::default());
        }
        let t = self.tallies.get_mut(key).expect("inserted above");
        t.compared += 1;
        let (list, count) = match outcome {
            Outcome::Same => return,
            Outcome::Tie => {
                t.ties += 1;
                return;
            }
            Outcome::Artefact => {
                t.artefacts += 1;
                return;
            }
            Outcome::Loose => {
                t.loose += 1;
                (&mut self.loose_examples, t.loose)
            }
            Outcome::Refused => {
                t.failures += 1;
                (&mut self.messages, t.failures)
            }
        };
        if count <= 8 {
            list.push(format!("{key}: {}", what()));
        }
    }
}

/// How one answer compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    Same,
    Tie,
    Artefact,
    Loose,
    Refused,
}
