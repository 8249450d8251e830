//! The memory budget (`BuildConfig::memory_budget`): refused before the build when its first
//! phase alone is over it, stopped during it when a buffer would pass it, and no effect on
//! the tree when it is not reached.

use kdtree::{BuildConfig, BuildError, BuildStrategy, KdTree, first_phase_bytes};

/// Builds on one thread, so that the order of the buffers, and the peak, are the same on
/// every run.
fn build_one_thread(mesh: &scenes::Mesh, strategy: BuildStrategy, budget: Option<u64>) -> Result<KdTree, BuildError> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let config = BuildConfig { memory_budget: budget, strategy, ..BuildConfig::default() };
    pool.install(|| KdTree::build(&mesh.positions, &mesh.triangles, &config))
}

/// The exact build, and the binned one with binned nodes down to 512 triangles (several
/// binned levels on the arena).
const STRATEGIES: [BuildStrategy; 2] = [BuildStrategy::Exact, BuildStrategy::Binned { bins: 64, min_tris: 512 }];

#[test]
fn the_budget_stops_the_build_before_and_during_and_is_exact_at_the_peak() {
    for strategy in STRATEGIES {
        budget_at_its_limits(strategy);
    }
}

fn budget_at_its_limits(strategy: BuildStrategy) {
    let build_one_thread = |mesh: &scenes::Mesh, budget| build_one_thread(mesh, strategy, budget);
    let mesh = scenes::builtin::by_name("arena").unwrap().mesh;
    let first = first_phase_bytes(&mesh.positions, &mesh.triangles, strategy);
    let free = build_one_thread(&mesh, None).unwrap();
    let peak = free.build_peak_bytes().expect("a built tree has a peak");
    println!("arena, {strategy:?}: {} triangles, first phase {first} bytes, peak {peak} bytes", mesh.triangle_count());
    assert!(peak >= first && peak < 4 * first, "peak {peak}, first phase {first}");
    // The tree's own arrays are part of the peak.
    assert!(peak >= free.stats().bytes as u64);

    // Under the first phase: refused before the build, naming the estimate and the budget.
    let e = build_one_thread(&mesh, Some(first - 1)).unwrap_err();
    let BuildError::OverBudget { estimate, budget, stage } = &e else { panic!("{e:?}") };
    assert_eq!((*estimate, *budget), (first, first - 1));
    assert!(stage.contains("estimate"), "{stage}");
    let text = e.to_string();
    assert!(text.contains(&format!("{} bytes", first)) && text.contains(&format!("{} bytes", first - 1)), "{text}");

    // Under the peak: stopped during the build, at a buffer.
    let e = build_one_thread(&mesh, Some(peak - 1)).unwrap_err();
    let BuildError::OverBudget { estimate, budget, stage } = &e else { panic!("{e:?}") };
    assert!(*estimate > peak - 1 && *budget == peak - 1 && !stage.contains("estimate"), "{e}");

    // At the peak: the same tree as without a budget.
    let exact = build_one_thread(&mesh, Some(peak)).unwrap();
    assert_eq!(exact.layout_bytes(), free.layout_bytes());
    assert_eq!(exact.build_peak_bytes(), Some(peak));
}

#[test]
fn a_budget_far_above_the_need_changes_nothing() {
    for strategy in [BuildStrategy::Exact, BuildStrategy::Binned { bins: 16, min_tris: 64 }] {
        far_above_the_need(strategy);
    }
}

fn far_above_the_need(strategy: BuildStrategy) {
    let mesh = scenes::builtin::by_name("sphere").unwrap().mesh;
    let free =
        KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig { strategy, ..BuildConfig::default() }).unwrap();
    let config = BuildConfig { memory_budget: Some(1 << 40), strategy, ..BuildConfig::default() };
    let budgeted = KdTree::build(&mesh.positions, &mesh.triangles, &config).unwrap();
    assert_eq!(free.layout_bytes(), budgeted.layout_bytes());
    let e =
        KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig { memory_budget: Some(0), ..config }).unwrap_err();
    assert!(matches!(e, BuildError::OverBudget { budget: 0, .. }), "{e:?}");
}
