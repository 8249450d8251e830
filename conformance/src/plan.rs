//! What to check: a [`Plan`] of [`Check`]s (each method against its single-ray twin under a
//! [`Rule`]) and [`OracleCheck`]s (single-ray twins against the brute-force oracle).

use kdtree::Intersector;
use kdtree::isa::SimdLevel;
use trace::registry::{KDTREE, Options, Registry, SoftGrouping};

/// The tile sizes every tiled method is checked at (and the frame driver's tiles of the
/// others): 4, 8 and 16, with odd image sizes so that edge tiles are cut.
pub const TILES: [u32; 3] = [4, 8, 16];

/// Both triangle tests of our tree.
pub const INTERSECTORS: [Intersector; 2] = [Intersector::Wald, Intersector::Watertight];

/// How close a method's answers must be to its reference's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Rule {
    /// The reference's hit, or a tie: another triangle the test hits at exactly the same
    /// distance; the same any-hit answers. Our methods against `mono` on our tree.
    Exact,
    /// [`Rule::Exact`], or a difference the oracle accepts on our tree
    /// (`BruteForce::equivalent_hits` / `equivalent_occlusion`: rounding artefacts on
    /// triangles the ray cannot reach in exact arithmetic).
    Equivalent,
    /// The same tracer's other kernel (Embree's packets against its single rays): the
    /// reference's hit, or a tie within 1e-4 of its distance on a triangle that is either
    /// an edge neighbour — sharing a vertex or an edge with the reference's, whose point lies
    /// within 1e-4 of the triangles' size from it (the kernels round `t` differently by an
    /// ulp there, and the nearer neighbour wins) — or a coincident face, coplanar with it
    /// and holding both hit points (two faces hit at one `t`: the traversal order picks one); or, where the reference's
    /// hit (or the method's) lies on an edge of its triangle (a barycentric within 1e-6 of
    /// 0: a ray grazing a silhouette edge, as axis-parallel rays along the touching boxes'
    /// and the scaled arena's faces) or within the origin's rounding (64 ulps of its
    /// coordinates: a ray starting on a surface), a farther hit or a miss. Any-hit answers that differ
    /// (the same grazing rays) count against `Plan::loose_per_10k`.
    Ties,
    /// Another tracer's triangle test against ours: the same triangle, or another within
    /// 1e-4 of the distance (a tie at a shared edge or on coincident faces), or either hit on
    /// a triangle whose plane holds the ray (a measure-zero case each test answers its own
    /// way), on all but
    /// `Plan::loose_per_10k` in 10,000 answers; everything else is counted and reported.
    Loose,
}

/// One method checked against one reference, both by full registry name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Check {
    /// The method: `mft-8`, `embree-16`.
    pub method: String,
    /// Its options (the frame driver's tile for untiled methods; culling).
    pub options: Options,
    /// The single-ray method it must agree with: `mono`, `embree-1`.
    pub reference: String,
    /// How closely.
    pub rule: Rule,
}

/// Which brute force a single-ray twin is checked against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OracleTest {
    /// The tree's triangle test (our methods).
    Tree,
    /// Always this test (a baseline that runs our Wald records whatever the tree's test).
    Fixed(Intersector),
}

/// A single-ray method checked against the brute-force oracle on the cases marked for it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OracleCheck {
    /// The method's full name.
    pub method: String,
    /// Which oracle.
    pub test: OracleTest,
    /// [`Rule::Exact`]: `BruteForce::check` must accept every answer; [`Rule::Loose`]:
    /// rejections are counted like loose disagreements.
    pub rule: Rule,
}

/// What to check.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Methods against references.
    pub checks: Vec<Check>,
    /// Single-ray twins against the oracle.
    pub oracles: Vec<OracleCheck>,
    /// The trees' triangle tests.
    pub intersectors: Vec<Intersector>,
    /// How many answers in 10,000 may disagree under [`Rule::Loose`] (per check and query).
    pub loose_per_10k: f64,
}

impl Plan {
    /// Every method of `registry` on our kd-tree but `mono` itself against `mono`, exactly
    /// ([`Rule::Exact`]), at tiles 4, 8 and 16 (tiled methods also without packet/leaf
    /// culling at 8, and those with a per-point soft-shadow kernel also with it at 8; at
    /// tiles 8 and 16 also at each narrower SIMD level the CPU runs, `sse4.1` and `avx2`, and
    /// with 8-lane packets where it runs AVX2, so that every packet width and lane type is
    /// checked: 4, 8, 16 in two AVX2 registers and 16 in one AVX-512 register), with both
    /// intersectors; `mono` against the oracle.
    pub fn ours(registry: &Registry) -> Plan {
        let mut checks = Vec::new();
        for e in registry.entries().iter().filter(|e| e.structure == KDTREE) {
            for tile in TILES {
                if e.name == "mono" {
                    continue; // the reference itself
                }
                if e.tiled && !tile.is_multiple_of(e.tile_multiple) {
                    continue; // a tile the method cannot take (mft-x16: a multiple of 8)
                }
                let method = if e.tiled { format!("{}-{tile}", e.name) } else { e.name.to_string() };
                let options = Options { tile, ..Options::default() };
                checks.push(Check { method: method.clone(), options, reference: "mono".into(), rule: Rule::Exact });
                if e.per_point.is_some() && tile == 8 {
                    let options = Options { soft: SoftGrouping::PerPoint, ..options };
                    checks.push(Check { method: method.clone(), options, reference: "mono".into(), rule: Rule::Exact });
                }
                if e.tiled && tile == 8 {
                    let options = Options { culling: false, ..options };
                    checks.push(Check { method: method.clone(), options, reference: "mono".into(), rule: Rule::Exact });
                }
                // Every narrower SIMD level this CPU runs (the default is its widest): each
                // packet width's kernels, at tiles 8 and 16.
                if tile >= 8 {
                    for simd in [SimdLevel::Sse41, SimdLevel::Avx2].into_iter().filter(|l| *l < options.simd) {
                        let options = Options { simd, ..options };
                        checks.push(Check {
                            method: method.clone(),
                            options,
                            reference: "mono".into(),
                            rule: Rule::Exact,
                        });
                    }
                    // The 8-lane packets (one AVX2 register), which no level binds by
                    // default (16 lanes from `avx2` on).
                    if options.simd >= SimdLevel::Avx2 {
                        let options = Options { packet_lanes: Some(8), ..options };
                        checks.push(Check {
                            method: method.clone(),
                            options,
                            reference: "mono".into(),
                            rule: Rule::Exact,
                        });
                    }
                }
            }
        }
        let oracles = vec![OracleCheck { method: "mono".into(), test: OracleTest::Tree, rule: Rule::Exact }];
        Plan { checks, oracles, intersectors: INTERSECTORS.to_vec(), loose_per_10k: 1.0 }
    }
}
