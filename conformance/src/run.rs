//! Running a [`Plan`] over [`Case`]s: every check traced through the frame driver, per case,
//! intersector and camera, its answers judged and tallied in a [`Report`].

use std::cell::OnceCell;
use std::collections::{BTreeSet, HashMap};

use cones::shadows::{SAMPLES, light_samples, shadow_rays};
use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Hit, KdTree, Ray};
use scenes::SphereLight;
use trace::frame::{SoftStats, TileLayout, View};
use trace::method::{hard_shadow_segment, primary_ray};
use trace::registry::{KDTREE, Options, Registry, SoftGrouping, Structures};
use trace::soft;

use crate::cases::Case;
use crate::judge::{Judge, on_edge};
use crate::plan::{OracleTest, Plan, Rule};
use crate::report::{Outcome, REPORTED, Report};

/// Soft-shadow light radius in Sponza units (thesis Table 4.6's larger light).
pub const LIGHT_RADIUS: f32 = 2.0;

/// The passes of one method on one camera, in the layout's tile order.
struct Frame {
    hits: Vec<Option<Hit>>,
    shadow: Vec<bool>,
    shadow_counts: (u64, u64),
    visible: Vec<f32>,
    soft: SoftStats,
}

/// Blocked soft-shadow rays of a pixel from its visible fraction.
fn blocked(visible: f32) -> u32 {
    ((1.0 - visible) * SAMPLES as f32).round() as u32
}

/// Runs `plan` over `cases` with the methods of `registry`; see the crate documentation.
///
/// Panics when a case's tree or a structure fails to build or a method fails to bind (a
/// broken registry, not a wrong answer).
pub fn run(registry: &Registry, plan: &Plan, cases: &[Case]) -> Report {
    let mut report = Report { loose_per_10k: plan.loose_per_10k, ..Report::default() };
    let names = plan.checks.iter().map(|c| c.method.as_str()).chain(plan.checks.iter().map(|c| c.reference.as_str()));
    let needed: BTreeSet<&'static str> = names
        .chain(plan.oracles.iter().map(|o| o.method.as_str()))
        .map(|n| registry.entry(registry.select(n, Options::default()).expect("a registered method").entry).structure)
        .filter(|&s| s != KDTREE)
        .collect();
    for case in cases {
        for &intersector in &plan.intersectors {
            let config = BuildConfig { intersector, ..BuildConfig::default() };
            let mesh = &case.scene.mesh;
            let tree = KdTree::build(&mesh.positions, &mesh.triangles, &config)
                .unwrap_or_else(|e| panic!("{}: the tree does not build: {e}", case.name));
            let mut structures = Structures::new(&tree);
            for &name in &needed {
                let entry = registry.structure(name).unwrap_or_else(|| panic!("no structure '{name}'"));
                let built = (entry.build)(&case.scene).unwrap_or_else(|e| panic!("{}: {name}: {e}", case.name));
                structures.insert(name, built);
            }
            let judge = Judge { tree: &tree, oracle: OnceCell::new() };
            let light = soft::scene_light(&case.scene, &tree, LIGHT_RADIUS);
            let at = format!("{} {intersector:?}", case.name);
            if case.oracle {
                check_oracles(registry, plan, case, &tree, &structures, &at, &mut report);
            }
            check_case(registry, plan, case, &structures, &judge, &light, &at, &mut report);
        }
    }
    report
}

/// [`run()`] as a test: prints the report's summary on stderr, then panics if any key fails
/// ([`Report::assert_ok`]). Returns the report.
pub fn assert_conforms(registry: &Registry, plan: &Plan, cases: &[Case]) -> Report {
    let report = run(registry, plan, cases);
    eprintln!("{}", report.summary());
    report.assert_ok();
    report
}

/// Binds `name` with `options` (panics on a broken registry).
fn bind<'s>(registry: &Registry, name: &str, options: Options, s: &'s Structures<'_>) -> trace::Bound<'s> {
    let selected = registry.select(name, options).unwrap_or_else(|e| panic!("{e}"));
    registry.bind(&selected, s).unwrap_or_else(|e| panic!("{e}"))
}

/// The single-ray twins against the brute-force oracle on the stream and primary rays.
fn check_oracles(
    registry: &Registry,
    plan: &Plan,
    case: &Case,
    tree: &KdTree,
    structures: &Structures<'_>,
    at: &str,
    report: &mut Report,
) {
    let mut rays = case.rays.clone();
    for (_, camera) in &case.cameras {
        rays.extend((0..camera.height).flat_map(|y| (0..camera.width).map(move |x| primary_ray(camera, x, y))));
    }
    for o in &plan.oracles {
        let oracle = match o.test {
            OracleTest::Tree => BruteForce::for_tree(tree),
            OracleTest::Fixed(test) => {
                let tris: Vec<[Vec3; 3]> =
                    (0..case.scene.mesh.triangle_count()).map(|i| case.scene.mesh.triangle(i)).collect();
                BruteForce::new(&tris, test)
            }
        };
        let m = bind(registry, &o.method, Options::default(), structures);
        let (mut hits, mut occluded) = (vec![None; rays.len()], vec![false; rays.len()]);
        m.tracer.stream(&rays, &mut hits);
        m.tracer.stream_occluded(&rays, &mut occluded);
        let key = match o.rule {
            Rule::Loose => format!("{} vs brute force: rays {REPORTED}", o.method),
            _ => format!("{} vs brute force: rays", o.method),
        };
        for (i, ray) in rays.iter().enumerate() {
            let outcome = match oracle.check(ray, hits[i], occluded[i]) {
                Ok(()) => Outcome::Same,
                // Another triangle test: the oracle's hit within 1e-4 of the distance.
                Err(_) if o.rule == Rule::Loose => {
                    let want = oracle.intersect(ray);
                    let near = match (hits[i], want) {
                        (Some(g), Some(w)) => (g.t - w.t).abs() <= 1e-4 * g.t.abs().max(w.t.abs()),
                        (g, w) => g.is_none() && w.is_none(),
                    };
                    if near && occluded[i] == want.is_some() { Outcome::Tie } else { Outcome::Loose }
                }
                Err(_) => Outcome::Refused,
            };
            report.record(&key, outcome, || {
                format!("{at}: ray {i}: {:?}", oracle.check(ray, hits[i], occluded[i]).unwrap_err())
            });
        }
    }
}

/// Every check of `plan` on one built case.
#[allow(clippy::too_many_arguments)]
fn check_case(
    registry: &Registry,
    plan: &Plan,
    case: &Case,
    structures: &Structures<'_>,
    judge: &Judge<'_>,
    light: &SphereLight,
    at: &str,
    report: &mut Report,
) {
    let scene = &case.scene;
    let surfaces = &trace::shade::surfaces(&scene.mesh);
    // The references' answers: per (reference, tile, camera) frames; per reference streams.
    let mut frames: HashMap<(String, u32, usize), Frame> = HashMap::new();
    let mut streams: HashMap<String, (Vec<Option<Hit>>, Vec<bool>)> = HashMap::new();
    let trace_stream = |m: &trace::Bound<'_>| {
        let (mut hits, mut occluded) = (vec![None; case.rays.len()], vec![false; case.rays.len()]);
        m.tracer.stream(&case.rays, &mut hits);
        m.tracer.stream_occluded(&case.rays, &mut occluded);
        (hits, occluded)
    };
    // Most soft-shadow kernels take no tile: one check per method, kernel (with its tile
    // where it takes one, `Bound::kernels`) and rule.
    let mut soft_done: BTreeSet<(&'static str, String, String, Rule)> = BTreeSet::new();
    for check in &plan.checks {
        let m = bind(registry, &check.method, check.options, structures);
        let kernel = m.kernels.soft.clone();
        let soft = soft_done.insert((m.entry.name, kernel, check.reference.clone(), check.rule));
        let tile = m.options.tile;
        let reference = bind(registry, &check.reference, Options { tile, ..Options::default() }, structures);
        let label = format!(
            "{} (tile {tile}, simd {}{}{}) vs {} [{:?}]",
            check.method,
            check.options.simd,
            if check.options.culling { "" } else { ", no culling" },
            if check.options.soft == SoftGrouping::PerPoint { ", per-point soft shadows" } else { "" },
            check.reference,
            check.rule
        );
        let key = |query: &str| format!("{label}: {query}");
        let [k_primary, k_shadow, k_soft, k_counts, k_stream, k_occluded] =
            ["primary", "shadow", "soft", "pass counts", "stream", "stream occluded"].map(key);
        let (k_stream, k_occluded) = if check.rule == Rule::Loose {
            (format!("{k_stream} {REPORTED}"), format!("{k_occluded} {REPORTED}"))
        } else {
            (k_stream, k_occluded)
        };
        for (ci, (view, camera)) in case.cameras.iter().enumerate() {
            report.views += 1;
            let layout = TileLayout::new(camera.width, camera.height, tile);
            let want = frames.entry((check.reference.clone(), tile, ci)).or_insert_with(|| {
                let mut hits = vec![None; layout.pixel_count()];
                reference.tracer.primary(&layout, camera, &mut hits, None);
                let mut shadow = vec![false; layout.pixel_count()];
                let shadow_counts = reference.tracer.shadow(
                    &View { layout: &layout, scene, surfaces, camera },
                    &hits,
                    &mut shadow,
                    None,
                );
                let mut visible = vec![0.0; layout.pixel_count()];
                let soft = reference.tracer.soft(
                    &View { layout: &layout, scene, surfaces, camera },
                    &hits,
                    light,
                    &mut visible,
                    None,
                );
                Frame { hits, shadow, shadow_counts, visible, soft }
            });
            let n = layout.pixel_count();
            let (mut hits, mut shadow, mut visible) = (vec![None; n], vec![false; n], vec![0.0; n]);
            m.tracer.primary(&layout, camera, &mut hits, None);
            // Shadows from the reference's hits, so that both trace the same rays.
            let counts =
                m.tracer.shadow(&View { layout: &layout, scene, surfaces, camera }, &want.hits, &mut shadow, None);
            let stats = if soft {
                m.tracer.soft(&View { layout: &layout, scene, surfaces, camera }, &want.hits, light, &mut visible, None)
            } else {
                want.soft
            };
            if !soft {
                visible.copy_from_slice(&want.visible);
            }
            let pixels = layout.tiles().iter().flat_map(|t| t.pixels());
            for (i, (x, y)) in pixels.enumerate() {
                let where_ = || format!("{at}, view {view}, pixel ({x}, {y})");
                let ray = primary_ray(camera, x, y);
                let outcome = judge.hit(check.rule, &ray, hits[i], want.hits[i]);
                report.record(&k_primary, outcome, || {
                    format!("{}: got {:?}, reference {:?}", where_(), hits[i], want.hits[i])
                });
                // Shadow rays that start on an edge (their primary ray grazed it) graze what
                // meets that edge: another triangle test may see them either way.
                let from_edge = check.rule == Rule::Loose && want.hits[i].is_some_and(on_edge);
                let outcome = match hard_shadow_segment(scene, surfaces, camera, x, y, &want.hits[i])
                    .map(|(s, e)| Ray::segment(s, e))
                {
                    Some(_) if from_edge && shadow[i] != want.shadow[i] => Outcome::Tie,
                    Some(r) => judge.occlusion(check.rule, &r, shadow[i], want.shadow[i]),
                    None if shadow[i] => Outcome::Refused,
                    None => Outcome::Same,
                };
                report.record(&k_shadow, outcome, || {
                    format!("{}: blocked {}, reference {}", where_(), shadow[i], want.shadow[i])
                });
                let (got_n, want_n) = (blocked(visible[i]), blocked(want.visible[i]));
                let outcome = if got_n == want_n && visible[i] == want.visible[i] {
                    Outcome::Same
                } else if from_edge {
                    Outcome::Tie
                } else {
                    let rays = want.hits[i]
                        .as_ref()
                        .and_then(|h| soft::shadow_start(surfaces, light, h, ray.dir))
                        .and_then(|(start, _)| Some(shadow_rays(start, &light_samples(start, light)?)));
                    judge.soft(check.rule, rays.as_ref().map_or(&[][..], |r| &r[..]), got_n, want_n)
                };
                report.record(&k_soft, outcome, || format!("{}: {got_n} of 16 blocked, reference {want_n}", where_()));
            }
            let same_counts =
                counts.0 == want.shadow_counts.0 && (stats.points, stats.rays) == (want.soft.points, want.soft.rays);
            let exact = check.rule != Rule::Loose;
            let counts_ok = same_counts && (!exact || counts == want.shadow_counts || check.rule == Rule::Equivalent);
            let outcome = if counts_ok {
                Outcome::Same
            } else if exact {
                Outcome::Refused
            } else {
                Outcome::Loose
            };
            report.record(&k_counts, outcome, || {
                format!(
                    "{at}, view {view}: shadow {counts:?} vs {:?}, soft {stats:?} vs {:?}",
                    want.shadow_counts, want.soft
                )
            });
        }
        let want = streams.entry(check.reference.clone()).or_insert_with(|| trace_stream(&reference));
        let (hits, occluded) = trace_stream(&m);
        for (i, ray) in case.rays.iter().enumerate() {
            report.record(&k_stream, judge.hit(check.rule, ray, hits[i], want.0[i]), || {
                format!("{at}: ray {i} {ray:?}: got {:?}, reference {:?}", hits[i], want.0[i])
            });
            let outcome = judge.occlusion(check.rule, ray, occluded[i], want.1[i]);
            report.record(&k_occluded, outcome, || {
                format!("{at}: ray {i} {ray:?}: got {}, reference {}", occluded[i], want.1[i])
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use cones::Cone;
    use kdtree::Intersector;
    use scenes::{Camera, Tile};
    use trace::method::{Method, ShadowJob, SingleRays, TileCounters};
    use trace::registry::{Binding, Entry};

    use super::*;
    use crate::cases::{builtin_cases, soup_cases};
    use crate::plan::{Check, OracleCheck};

    /// Single rays with one query deliberately wrong on some rays: `K` = 0 primary, 1 hard
    /// shadow, 2 soft shadow, 3 stream, 4 stream any-hit.
    struct Faulty<'a, const K: u8>(SingleRays<&'a KdTree>);

    impl<const K: u8> Method for Faulty<'_, K> {
        type Scratch = ();

        fn scratch(&self) {}

        fn primary_tile<C: TileCounters>(&self, s: &mut (), c: &Camera, t: &Tile, out: &mut [Option<Hit>], n: &mut C) {
            self.0.primary_tile(s, c, t, out, n);
            if K == 0 {
                out.iter_mut().filter(|h| h.is_some()).step_by(7).for_each(|h| *h = None);
            }
        }

        fn shadow_tile<C: TileCounters>(
            &self,
            s: &mut (),
            job: &ShadowJob<'_>,
            out: &mut [bool],
            n: &mut C,
        ) -> (u64, u64) {
            let counts = self.0.shadow_tile(s, job, out, n);
            if K == 1 {
                out.iter_mut().zip(job.hits).filter(|(_, h)| h.is_some()).step_by(5).for_each(|(b, _)| *b = !*b);
            }
            counts
        }

        fn soft_point<C: TileCounters>(&self, s: &mut (), rays: &[Ray; SAMPLES], cone: &Cone, n: &mut C) -> u16 {
            self.0.soft_point(s, rays, cone, n) ^ u16::from(K == 2)
        }

        fn stream<C: TileCounters>(&self, s: &mut (), rays: &[Ray], out: &mut [Option<Hit>], n: &mut C) {
            self.0.stream(s, rays, out, n);
            if K == 3 {
                out.iter_mut().filter(|h| h.is_some()).step_by(9).for_each(|h| *h = None);
            }
        }

        fn stream_occluded<C: TileCounters>(&self, s: &mut (), rays: &[Ray], out: &mut [bool], n: &mut C) {
            self.0.stream_occluded(s, rays, out, n);
            if K == 4 {
                out.iter_mut().step_by(9).for_each(|b| *b = !*b);
            }
        }
    }

    fn faulty(name: &'static str, bind: trace::registry::Bind) -> Entry {
        Entry::whole(name, "test", "wrong on purpose", KDTREE, bind)
    }

    fn registry() -> Registry {
        let mut r = Registry::ours();
        r.add(faulty("faulty-primary", |s, _| Ok(Binding::method(Faulty::<0>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-shadow", |s, _| Ok(Binding::method(Faulty::<1>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-soft", |s, _| Ok(Binding::method(Faulty::<2>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-stream", |s, _| Ok(Binding::method(Faulty::<3>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-occluded", |s, _| Ok(Binding::method(Faulty::<4>(SingleRays(s.kdtree()))))));
        r
    }

    fn plan(method: &str, rule: Rule) -> Plan {
        let check = Check { method: method.into(), options: Options::default(), reference: "mono".into(), rule };
        Plan { checks: vec![check], oracles: Vec::new(), intersectors: vec![Intersector::Wald], loose_per_10k: 1.0 }
    }

    fn cases() -> Vec<Case> {
        let mut cases =
            builtin_cases(13, 9, &["atrium", "arena", "atrium-rotated", "grove", "garage", "atrium-mirror"], &[]);
        cases.extend(soup_cases(1));
        cases
    }

    #[test]
    fn the_right_method_passes_and_each_wrong_query_is_caught() {
        let (r, cases) = (registry(), cases());
        let report = run(&r, &plan("mono", Rule::Exact), &cases);
        report.assert_ok();
        for query in ["primary", "shadow", "soft", "stream", "stream occluded"] {
            let t = report.tallies.iter().find(|(k, _)| k.ends_with(&format!(": {query}"))).unwrap().1;
            assert!(t.compared > 100, "{query}: {t:?}");
        }
        for (method, query) in [
            ("faulty-primary", ": primary"),
            ("faulty-shadow", ": shadow"),
            ("faulty-soft", ": soft"),
            ("faulty-stream", ": stream"),
            ("faulty-occluded", ": stream occluded"),
        ] {
            for rule in [Rule::Exact, Rule::Equivalent, Rule::Ties, Rule::Loose] {
                let report = run(&r, &plan(method, rule), &cases);
                if rule == Rule::Loose && query.starts_with(": stream") {
                    // Loose streams are reported, not judged: the faults must show in the tally.
                    let (_, t) = report
                        .tallies
                        .iter()
                        .find(|(k, _)| k.contains(&format!("{query} {REPORTED}")))
                        .expect("the stream is tallied");
                    assert!(t.loose > 0, "{method} {rule:?}: {t:?}");
                    continue;
                }
                let failing = report.failing();
                assert!(failing.iter().any(|k| k.contains(&format!("{query}:"))), "{method} {rule:?}: {failing:?}");
            }
        }
    }

    #[test]
    fn a_wrong_single_ray_twin_fails_the_oracle() {
        let r = registry();
        let mut p = plan("mono", Rule::Exact);
        p.oracles = vec![OracleCheck { method: "faulty-stream".into(), test: OracleTest::Tree, rule: Rule::Exact }];
        let failing = run(&r, &p, &soup_cases(1)).failing();
        assert!(failing.iter().any(|k| k.starts_with("faulty-stream vs brute force")), "{failing:?}");
        p.oracles[0].method = "mono".into();
        run(&r, &p, &soup_cases(1)).assert_ok();
    }
}
