//! OBJ bytes -> loader: never panics; whatever it accepts passes `Mesh::check`. The same bytes
//! as an MTL material library: never panics; every material it accepts passes
//! `Material::check`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok((mesh, report)) = scenes::obj::parse_obj(data, std::path::Path::new("fuzz.obj")) {
        mesh.check().expect("a loaded mesh satisfies its invariants");
        assert_eq!(report.triangles, mesh.triangle_count());
        assert!(mesh.triangle_count() > 0);
    }
    if let Ok(materials) = scenes::mtl::parse_mtl(data, std::path::Path::new("fuzz.mtl")) {
        for m in materials {
            m.check().expect("a loaded material satisfies its invariants");
        }
    }
});
