//! The closed-form case: a sphere above a plane lit by a spherical light. Stratified
//! estimates of the visible fraction converge to the closed form (error falling like
//! `1 / sqrt(N)` or faster), and the edge-width result is measured against it.

use edgewidth::analytic::sphere_visible_fraction;
use edgewidth::sampling::{AreaLight, Rng, ShadingPoint, visible_fraction};
use edgewidth::{EdgeScratch, LeakRemedies, edge_width, occlusion_factor, width_from_light};
use glam::Vec3;
use kdtree::{BuildConfig, KdTree, Ray};
use scenes::SphereLight;
use scenes::builtin::shapes::{MeshBuilder, Part};

const OCCLUDER: (Vec3, f32) = (Vec3::new(0.0, 2.0, 0.0), 1.0);

fn scene() -> (KdTree, AreaLight) {
    let mut b = MeshBuilder::new();
    let m = b.material("m", Vec3::ONE);
    b.add(&Part::icosphere(OCCLUDER.1, 5).translated(OCCLUDER.0), m);
    b.add_box(Vec3::new(-20.0, -1.0, -20.0), Vec3::new(20.0, 0.0, 20.0), m);
    let mesh = b.finish();
    let tree = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig::default()).unwrap();
    let light = AreaLight::Sphere(SphereLight { center: Vec3::new(0.6, 8.0, 0.0), radius: 1.0, intensity: Vec3::ONE });
    (tree, light)
}

/// Points on the plane inside the penumbra (closed form strictly between 0.02 and 0.98),
/// with their shading points and closed-form fractions.
fn penumbra(tree: &KdTree, light: &AreaLight) -> Vec<(ShadingPoint, f64)> {
    let mut rng = Rng::new(17);
    let mut out = Vec::new();
    while out.len() < 150 {
        let (x, z) = (rng.next_f32() * 6.0 - 3.0, rng.next_f32() * 6.0 - 3.0);
        let down = Ray::new(Vec3::new(x, 0.5, z), -Vec3::Y, 0.0, f32::INFINITY);
        let hit = tree.intersect(&down).unwrap();
        let p = ShadingPoint::new(tree.triangle(hit.prim), hit, -Vec3::Y);
        let exact = sphere_visible_fraction(p.point, light.center(), light.radius(), OCCLUDER.0, OCCLUDER.1);
        if exact > 0.02 && exact < 0.98 {
            out.push((p, exact));
        }
    }
    out
}

fn rmse(errors: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for e in errors {
        sum += e * e;
        n += 1.0;
    }
    (sum / n).sqrt()
}

#[test]
fn stratified_estimates_converge_to_the_closed_form() {
    let (tree, light) = scene();
    let points = penumbra(&tree, &light);
    let mut errors = Vec::new();
    for n in [4u32, 16, 64, 256, 1024] {
        let mut rng = Rng::new(u64::from(n));
        let e =
            rmse(points.iter().map(|(p, exact)| f64::from(visible_fraction(&tree, &light, p, n, &mut rng)) - exact));
        errors.push((n, e));
    }
    let (n0, e0) = errors[0];
    for &(n, e) in &errors {
        // 1/sqrt(N) from the first, with 30% latitude and a floor for the tessellated sphere.
        let bound = 1.3 * e0 * (f64::from(n0) / f64::from(n)).sqrt() + 0.003;
        assert!(e <= bound, "N = {n}: rmse {e} above {bound} ({errors:?})");
    }
    assert!(errors[4].1 < 0.01, "the limit is the closed form: {errors:?}");
}

#[test]
fn edge_widths_are_measured_against_the_closed_form() {
    let (tree, light) = scene();
    let points = penumbra(&tree, &light);
    let mut scratch = EdgeScratch::default();
    let (mut hard, mut ew) = (Vec::new(), Vec::new());
    for (p, exact) in &points {
        let center = light.center();
        let ray = p.shadow_ray(center).unwrap();
        let r = width_from_light(light.radius(), (center - p.point).length(), 1.0);
        let w = edge_width(&tree, &ray, r, &LeakRemedies::default(), &mut scratch);
        let blocked = tree.occluded(&ray);
        // The edge width sees an occluder exactly when the hard shadow does.
        assert_eq!(w > 0.0, blocked);
        hard.push(f64::from(u8::from(!blocked)) - exact);
        ew.push(f64::from(1.0 - occlusion_factor(w, r)) - exact);
    }
    // The edge width only lightens the hard shadow (its penumbra lies inside the hard
    // shadow, Figure 5.6), never darkens a lit point.
    assert!(ew.iter().zip(&hard).all(|(e, h)| e >= h));
    let (hard, ew) = (rmse(hard.into_iter()), rmse(ew.into_iter()));
    // Reported, not asserted: the one-sided penumbra cannot fix the lit half of the true
    // penumbra, so the edge width is not much better than hard shadows here (see README).
    eprintln!("penumbra rmse against the closed form: hard {hard:.4}, edge width {ew:.4}");
    assert!(ew.is_finite() && hard > 0.0);
}
