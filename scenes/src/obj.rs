//! Wavefront OBJ loading, plain or gzip-compressed, into one [`Mesh`].
//!
//! The parser is our own rather than `tobj`'s because the benchmark needs things `tobj` does not
//! give: primitive ids in the file's face order (counting the degenerate triangles we drop),
//! `usemtl` names without a material library, and errors that name the line, vertex or face.
//! The tests check that it reads the same positions and triangles as `tobj` (a fan from each
//! polygon's first corner, as `tobj` triangulates) on small files and on the shared scenes.
//!
//! Only geometry and material names are read: `v` lines (extra `w` or colour values are
//! ignored), `f` lines (the position index of each corner, absolute or negative-relative;
//! texture and normal indices are ignored), `usemtl` names and `mtllib` names (several on a
//! line, several lines, up to a `#` comment). Everything else (`vt`, `vn`, `g`, `o`, `s`,
//! `l`, ...) is skipped.
//!
//! [`load_obj`] then reads the named material libraries (see [`crate::mtl`]) from the OBJ
//! file's folder and gives each `usemtl` name the material they define. A library that is not
//! there is no error (the materials keep the default, and [`LoadReport`] lists it); a library
//! that is there but malformed is. Geometry, triangle order and `prim_ids` never depend on the
//! libraries.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use glam::Vec3;

use crate::{Material, Mesh, SceneError, mtl};

/// What the loader read and what it dropped.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LoadReport {
    /// `v` lines in the file.
    pub vertices: usize,
    /// `f` lines in the file (polygons before triangulation).
    pub faces: usize,
    /// Triangles kept in the mesh.
    pub triangles: usize,
    /// Degenerate triangles dropped: coincident corner indices or an exactly zero cross
    /// product of the edges in f32.
    pub degenerate_dropped: usize,
    /// The material libraries that `mtllib` lines name, as written, in file order, each once.
    pub material_libraries: Vec<String>,
    /// Those of [`Self::material_libraries`] that [`load_obj`] did not find (relative to the
    /// OBJ file's folder): not an error, their materials keep the default. [`parse_obj`],
    /// which reads no other file, leaves this empty.
    pub missing_material_libraries: Vec<String>,
    /// Materials of the mesh that a library defines; the others ([`parse_obj`]: all) are
    /// `Material::default()` under their `usemtl` name.
    pub materials_from_libraries: usize,
}

impl LoadReport {
    /// All triangles of the file after fan triangulation, kept or dropped: the sum over faces
    /// of (corners - 2), the count that `SOURCES.md` lists for the shared scenes.
    pub fn source_triangles(&self) -> usize {
        self.triangles + self.degenerate_dropped
    }
}

/// The gzip magic bytes.
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// Loads an `.obj` or `.obj.gz` file (gzip is recognised by its magic bytes, whatever the
/// extension) and merges all its objects into one mesh.
///
/// Polygons are triangulated as fans from their first corner, `prim_ids` number the triangles
/// in file order counting the dropped degenerate ones, and each `usemtl` name becomes a
/// [`Material`]: the one the `mtllib` libraries define under that name (read from the OBJ
/// file's folder, later libraries overriding earlier ones), else the default diffuse one
/// under that name (faces before any `usemtl` use a material named `default`). Errors name the
/// file and, for malformed content, the line (of the OBJ or of the `.mtl` file). A vertex
/// coordinate that is NaN or infinite (`nan`, `inf`, or a number beyond `f32`, such as
/// `1e39`) is such an error, naming the line and the vertex. A library that does not exist is
/// not an error: [`LoadReport::missing_material_libraries`] names it.
pub fn load_obj(path: &Path) -> Result<(Mesh, LoadReport), SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })?;
    let (mut mesh, mut report) = if bytes.starts_with(&GZIP_MAGIC) {
        let mut text = Vec::with_capacity(bytes.len() * 6);
        flate2::read::MultiGzDecoder::new(&bytes[..])
            .read_to_end(&mut text)
            .map_err(|e| SceneError::Parse { path: path.to_path_buf(), message: format!("corrupt gzip data: {e}") })?;
        parse_obj(&text, path)?
    } else {
        parse_obj(&bytes, path)?
    };
    apply_material_libraries(&mut mesh, &mut report, path.parent().unwrap_or(Path::new("")))?;
    Ok((mesh, report))
}

/// Reads the libraries of `report.material_libraries` from `folder` and replaces each mesh
/// material that one defines (by name) with its definition; records the missing libraries.
fn apply_material_libraries(mesh: &mut Mesh, report: &mut LoadReport, folder: &Path) -> Result<(), SceneError> {
    let mut defined: HashMap<String, Material> = HashMap::new();
    for name in &report.material_libraries {
        let path = folder.join(name);
        match std::fs::read(&path) {
            Ok(bytes) => defined.extend(mtl::parse_mtl(&bytes, &path)?.into_iter().map(|m| (m.name.clone(), m))),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => report.missing_material_libraries.push(name.clone()),
            Err(source) => return Err(SceneError::Io { path, source }),
        }
    }
    for material in &mut mesh.materials {
        if let Some(definition) = defined.get(&material.name) {
            *material = definition.clone();
            report.materials_from_libraries += 1;
        }
    }
    Ok(())
}

/// Parses OBJ text already in memory; `origin` is only used in error messages. Reads no
/// other file: `mtllib` names are listed in [`LoadReport::material_libraries`], and every
/// material is `Material::default()` under its `usemtl` name ([`load_obj`] reads the
/// libraries).
pub fn parse_obj(text: &[u8], origin: &Path) -> Result<(Mesh, LoadReport), SceneError> {
    let err = |line: usize, message: String| SceneError::Parse {
        path: origin.to_path_buf(),
        message: format!("line {line}: {message}"),
    };
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut material_ids: Vec<u32> = Vec::new();
    let mut materials: Vec<Material> = Vec::new();
    let mut material_index: HashMap<String, u32> = HashMap::new();
    let mut current_material = "default".to_string();
    let mut faces = 0usize;
    // Positive indices may in principle point at vertices defined later in the file; they are
    // checked once all vertices are known: (face number, line, zero-based index).
    let mut forward_refs: Vec<(usize, usize, u64)> = Vec::new();
    let mut corners: Vec<u32> = Vec::new();
    let mut libraries: Vec<String> = Vec::new();

    for (line_no, raw) in text.split(|&b| b == b'\n').enumerate() {
        let line_no = line_no + 1;
        let line = String::from_utf8_lossy(raw);
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let vertex = positions.len() + 1;
                let mut xyz = [0.0f32; 3];
                for c in &mut xyz {
                    let word = words
                        .next()
                        .ok_or_else(|| err(line_no, format!("vertex {vertex} has fewer than three coordinates")))?;
                    *c =
                        word.parse().map_err(|_| err(line_no, format!("vertex {vertex}: '{word}' is not a number")))?;
                }
                let p = Vec3::from_array(xyz);
                if !p.is_finite() {
                    return Err(err(line_no, format!("vertex {vertex} has a non-finite coordinate ({p})")));
                }
                positions.push(p);
            }
            Some("f") => {
                faces += 1;
                corners.clear();
                for word in words {
                    let index_text = word.split('/').next().unwrap_or_default();
                    let index: i64 = index_text
                        .parse()
                        .map_err(|_| err(line_no, format!("face {faces}: '{word}' is not a vertex index")))?;
                    let defined = positions.len() as i64;
                    let zero_based = match index {
                        0 => {
                            return Err(err(
                                line_no,
                                format!("face {faces} uses vertex index 0 (OBJ indices start at 1)"),
                            ));
                        }
                        i if i < 0 && defined + i < 0 => {
                            return Err(err(
                                line_no,
                                format!("face {faces} uses relative index {i} but only {defined} vertices precede it"),
                            ));
                        }
                        i if i < 0 => defined + i,
                        i => {
                            if i > defined {
                                forward_refs.push((faces, line_no, (i - 1) as u64));
                            }
                            i - 1
                        }
                    };
                    let zero_based = u32::try_from(zero_based).map_err(|_| {
                        err(line_no, format!("face {faces} uses vertex {index}, beyond the 32-bit range"))
                    })?;
                    corners.push(zero_based);
                }
                if corners.len() < 3 {
                    return Err(err(
                        line_no,
                        format!("face {faces} has {} corners; a face needs at least 3", corners.len()),
                    ));
                }
                let material = match material_index.get(&current_material) {
                    Some(&id) => id,
                    None => {
                        let id = materials.len() as u32;
                        materials.push(Material { name: current_material.clone(), ..Material::default() });
                        material_index.insert(current_material.clone(), id);
                        id
                    }
                };
                // Fan triangulation from the first corner, as tobj does.
                for i in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[i], corners[i + 1]]);
                    material_ids.push(material);
                }
            }
            Some("mtllib") => {
                // The names up to a comment.
                for name in words.take_while(|w| !w.starts_with('#')) {
                    if !libraries.iter().any(|l| l == name) {
                        libraries.push(name.to_string());
                    }
                }
            }
            Some("usemtl") => {
                let name = line.trim_start().strip_prefix("usemtl").unwrap_or_default().trim();
                current_material = if name.is_empty() { "default".to_string() } else { name.to_string() };
            }
            _ => {}
        }
    }

    if let Some(&(face, line, index)) = forward_refs.iter().find(|r| r.2 >= positions.len() as u64) {
        return Err(err(
            line,
            format!("face {face} references vertex {} but the file defines only {}", index + 1, positions.len()),
        ));
    }

    // Drop degenerate triangles, keeping each survivor's number in file order.
    let source_triangles = triangles.len();
    let mut mesh = Mesh { positions, materials, ..Mesh::default() };
    mesh.triangles.reserve(source_triangles);
    mesh.material_ids.reserve(source_triangles);
    mesh.prim_ids.reserve(source_triangles);
    for (prim, (tri, material)) in triangles.into_iter().zip(material_ids).enumerate() {
        if is_degenerate(&mesh.positions, tri) {
            continue;
        }
        let prim = u32::try_from(prim).map_err(|_| err(0, "more than 2^32 triangles".to_string()))?;
        mesh.triangles.push(tri);
        mesh.material_ids.push(material);
        mesh.prim_ids.push(prim);
    }
    let report = LoadReport {
        vertices: mesh.positions.len(),
        faces,
        triangles: mesh.triangles.len(),
        degenerate_dropped: source_triangles - mesh.triangles.len(),
        material_libraries: libraries,
        ..LoadReport::default()
    };
    if mesh.triangles.is_empty() {
        return Err(SceneError::Empty { path: origin.to_path_buf() });
    }
    Ok((mesh, report))
}

/// Whether a triangle has coincident corner indices or an exactly zero cross product in f32.
fn is_degenerate(positions: &[Vec3], [a, b, c]: [u32; 3]) -> bool {
    if a == b || b == c || a == c {
        return true;
    }
    let (pa, pb, pc) = (positions[a as usize], positions[b as usize], positions[c as usize]);
    (pb - pa).cross(pc - pa) == Vec3::ZERO
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;
    use std::path::PathBuf;

    fn parse(text: &str) -> Result<(Mesh, LoadReport), SceneError> {
        parse_obj(text.as_bytes(), Path::new("test.obj"))
    }

    fn error_text(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    /// A file `name` in a scratch folder of its own (removed when the folder is dropped).
    fn temp_path(name: &str) -> (crate::ScratchDir, PathBuf) {
        crate::scratch::scratch_file("scenes-obj-tests", name)
    }

    /// tobj's triangles as position triples, all models merged in order.
    fn tobj_triangles(text: &str) -> Vec<[Vec3; 3]> {
        let options = tobj::LoadOptions { triangulate: true, ..Default::default() };
        let (models, _) = tobj::load_obj_buf(&mut std::io::Cursor::new(text.as_bytes()), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .unwrap();
        let mut out = Vec::new();
        for m in models {
            let p = |i: u32| Vec3::from_slice(&m.mesh.positions[3 * i as usize..3 * i as usize + 3]);
            out.extend(m.mesh.indices.chunks_exact(3).map(|t| [p(t[0]), p(t[1]), p(t[2])]));
        }
        out
    }

    const PENTAGON: &str =
        "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nv 0 0 1\nf 1 2 3 4\nf 1/1/1 2/1/1 3 4 5\nf 6 2 3\n";

    #[test]
    fn polygons_become_fans_with_file_order_prim_ids() {
        let (mesh, report) = parse(PENTAGON).unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 3], [0, 3, 4], [5, 1, 2]]);
        assert_eq!(mesh.prim_ids, vec![0, 1, 2, 3, 4, 5]);
        assert_eq!(
            report,
            LoadReport { vertices: 6, faces: 3, triangles: 6, degenerate_dropped: 0, ..LoadReport::default() }
        );
        assert_eq!(mesh.materials, vec![Material::default()]);
        mesh.check().unwrap();
    }

    #[test]
    fn tobj_triangulates_the_same_fans() {
        let (mesh, _) = parse(PENTAGON).unwrap();
        let ours: Vec<[Vec3; 3]> = (0..mesh.triangle_count()).map(|i| mesh.triangle(i)).collect();
        assert_eq!(ours, tobj_triangles(PENTAGON));
    }

    #[test]
    fn degenerate_triangles_are_dropped_but_counted_in_prim_ids() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 3\nf -4 -3 -2\n";
        let (mesh, report) = parse(text).unwrap();
        assert_eq!(mesh.prim_ids, vec![0, 3]);
        assert_eq!(report.degenerate_dropped, 2);
        assert_eq!(report.triangles, 2);
        assert_eq!(report.source_triangles(), 4);
    }

    #[test]
    fn usemtl_names_become_materials() {
        let text =
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl stone\nf 1 2 3\nusemtl wood\nf 1 2 3\nusemtl stone\nf 3 2 1\n";
        let (mesh, _) = parse(text).unwrap();
        let names: Vec<&str> = mesh.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["default", "stone", "wood"]);
        assert_eq!(mesh.material_ids, vec![0, 1, 2, 1]);
    }

    #[test]
    fn bad_input_gives_clear_errors() {
        let e = error_text("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n");
        assert!(
            e.contains("test.obj") && e.contains("line 2") && e.contains("vertex 2") && e.contains("non-finite"),
            "{e}"
        );
        for coordinate in ["inf", "-inf", "1e39", "NaN", "-nan", "infinity"] {
            let e = error_text(&format!("v 0 0 0\nv 1 0 {coordinate}\n"));
            assert!(e.contains("line 2") && e.contains("vertex 2") && e.contains("non-finite"), "{coordinate}: {e}");
        }
        // (input, what its error names)
        let cases: [(&str, &[&str]); 8] = [
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n", &["face 2", "vertex 9", "line 5"]),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -7\n", &["face 1", "-7"]),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", &["index 0"]),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", &["face 1 has 2 corners"]),
            ("v 0 0\n", &["fewer than three"]),
            ("v 0 zero 0\n", &["'zero' is not a number"]),
            ("v 0 0 0\nf 1 x 1\n", &["'x' is not a vertex index"]),
            ("v 0 0 0\nf 1 99999999999 1\n", &["32-bit"]),
        ];
        for (input, names) in cases {
            let e = error_text(input);
            assert!(names.iter().all(|name| e.contains(name)), "{input:?}: {e}");
        }
        assert!(matches!(parse("# nothing\n"), Err(SceneError::Empty { .. })));
        assert!(matches!(parse("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"), Err(SceneError::Empty { .. })));
    }

    #[test]
    fn forward_references_are_allowed_when_the_vertex_exists() {
        let (mesh, _) = parse("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn tobj_rejects_out_of_range_indices_without_saying_where() {
        // What tobj itself does with the input we reject with a face number.
        let options = tobj::LoadOptions { triangulate: true, ..Default::default() };
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n";
        let result = tobj::load_obj_buf(&mut std::io::Cursor::new(text.as_bytes()), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        });
        assert_eq!(result.err(), Some(tobj::LoadError::FaceVertexOutOfBounds));
    }

    #[test]
    fn files_plain_and_gzipped_and_missing() {
        let (_plain_dir, plain) = temp_path("quad.obj");
        std::fs::write(&plain, PENTAGON).unwrap();
        let (_gz_dir, gz) = temp_path("quad.obj.gz");
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(PENTAGON.as_bytes()).unwrap();
        std::fs::write(&gz, enc.finish().unwrap()).unwrap();
        let a = load_obj(&plain).unwrap();
        let b = load_obj(&gz).unwrap();
        assert_eq!(a, b);
        let (_missing_dir, missing) = temp_path("missing.obj");
        let e = load_obj(&missing).unwrap_err();
        assert!(matches!(e, SceneError::Io { .. }) && e.to_string().contains("missing.obj"));
        let (_corrupt_dir, corrupt) = temp_path("corrupt.obj.gz");
        std::fs::write(&corrupt, [0x1f, 0x8b, 8, 0, 1, 2, 3]).unwrap();
        assert!(matches!(load_obj(&corrupt), Err(SceneError::Parse { .. })));
    }

    #[test]
    fn mtllib_names_are_listed_by_the_parser_which_reads_no_file() {
        let text =
            "mtllib a.mtl b.mtl\nmtllib sub/c.mtl a.mtl # c again\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
        let (mesh, report) = parse(text).unwrap();
        assert_eq!(report.material_libraries, ["a.mtl", "b.mtl", "sub/c.mtl"]);
        assert!(report.missing_material_libraries.is_empty());
        assert_eq!(report.materials_from_libraries, 0);
        assert_eq!(mesh.materials, vec![Material { name: "red".into(), ..Material::default() }]);
    }

    #[test]
    fn material_libraries_load_relative_to_the_obj_folder() {
        let dir = crate::ScratchDir::new("scenes-obj-mtllib", "libraries").unwrap();
        std::fs::create_dir_all(dir.join("scene/mats")).unwrap();
        let obj = format!(
            "mtllib first.mtl mats/second.mtl\nmtllib gone.mtl\n{}usemtl glass\nf 1 2 3 4\nusemtl paint\nf 1 2 3\n\
             usemtl nowhere\nf 1 2 4\nusemtl glass\nf 6 2 3\n",
            PENTAGON.lines().filter(|l| l.starts_with('v')).map(|l| format!("{l}\n")).collect::<String>()
        );
        std::fs::write(dir.join("scene/car.obj"), &obj).unwrap();
        std::fs::write(dir.join("scene/first.mtl"), "newmtl glass\nKd 0.1 0.1 0.1\nillum 2\n").unwrap();
        // The second library redefines glass (later libraries win) and defines paint.
        std::fs::write(
            dir.join("scene/mats/second.mtl"),
            "newmtl glass\nKs 0.1 0.1 0.1\nd 0.2\nNi 1.5\nillum 7\nnewmtl paint\nKd 0.6 0 0\nKs 0.5 0.5 0.5\nillum 3\n",
        )
        .unwrap();
        let (mesh, report) = load_obj(&dir.join("scene/car.obj")).unwrap();
        mesh.check().unwrap();
        assert_eq!(report.material_libraries, ["first.mtl", "mats/second.mtl", "gone.mtl"]);
        assert_eq!(report.missing_material_libraries, ["gone.mtl"]);
        assert_eq!(report.materials_from_libraries, 2);
        let shaders: Vec<(&str, crate::Shader)> =
            mesh.materials.iter().map(|m| (m.name.as_str(), m.shader())).collect();
        use crate::Shader::*;
        assert_eq!(shaders, [("glass", TransparentReflective), ("paint", Reflective), ("nowhere", Diffuse)]);
        assert_eq!(mesh.materials[2], Material { name: "nowhere".into(), ..Material::default() });
        assert_eq!(mesh.materials[1].diffuse, Vec3::new(0.6, 0.0, 0.0));
        assert_eq!(mesh.material_ids, vec![0, 0, 1, 2, 0]);
        // The geometry is exactly what the parser alone reads.
        let (plain, _) = parse(&obj).unwrap();
        assert_eq!(
            (&mesh.positions, &mesh.triangles, &mesh.prim_ids),
            (&plain.positions, &plain.triangles, &plain.prim_ids)
        );
        assert_eq!(mesh.material_ids, plain.material_ids);

        // A malformed library is an error naming it and its line.
        std::fs::write(dir.join("scene/mats/second.mtl"), "newmtl paint\n\nKd 0.6 0 1.5\n").unwrap();
        let e = load_obj(&dir.join("scene/car.obj")).unwrap_err().to_string();
        assert!(e.contains("second.mtl") && e.contains("line 3") && e.contains("'paint'"), "{e}");
        // A library that is a folder is an I/O error naming it, not a missing library.
        std::fs::remove_file(dir.join("scene/mats/second.mtl")).unwrap();
        std::fs::create_dir(dir.join("scene/mats/second.mtl")).unwrap();
        let e = load_obj(&dir.join("scene/car.obj")).unwrap_err();
        assert!(matches!(&e, SceneError::Io { path, .. } if path.ends_with("mats/second.mtl")), "{e}");
        // Every library missing: the load succeeds with default materials, all listed.
        std::fs::remove_dir_all(dir.join("scene/mats")).unwrap();
        std::fs::remove_file(dir.join("scene/first.mtl")).unwrap();
        let (mesh, report) = load_obj(&dir.join("scene/car.obj")).unwrap();
        assert_eq!(report.missing_material_libraries, ["first.mtl", "mats/second.mtl", "gone.mtl"]);
        assert_eq!(report.materials_from_libraries, 0);
        assert!(mesh.materials.iter().all(|m| m.shader() == crate::Shader::Diffuse && m.diffuse == Vec3::splat(0.75)));
    }

    /// Loads the shared benchmark scenes if present and checks their triangle counts against
    /// `SOURCES.md` (and, for Sponza, against tobj). Skips with a note when they are absent.
    #[test]
    fn shared_scenes_load_with_the_documented_counts() {
        let Some(dir) = crate::shared_scenes_dir() else {
            eprintln!("note: shared scenes folder not found; skipping");
            return;
        };
        // (file, vertices, triangles in the file).
        let expected = [
            ("sponza-dabrovic.obj.gz", 39_999, 66_454),
            ("stanford-bunny.obj.gz", 35_947, 69_451),
            ("kitchen-bart.obj.gz", 63_706, 110_561),
            ("sibenik.obj.gz", 40_981, 75_284),
            ("conference-mcguire.obj.gz", 194_399, 331_179),
        ];
        for (file, vertices, source_triangles) in expected {
            let path = dir.join(file);
            if !path.exists() {
                eprintln!("note: {} not found; skipping", path.display());
                continue;
            }
            let start = std::time::Instant::now();
            let (mesh, report) = load_obj(&path).unwrap();
            eprintln!("{file}: {report:?} in {:?}", start.elapsed());
            mesh.check().unwrap();
            assert_eq!(report.vertices, vertices, "{file}");
            assert_eq!(report.faces, source_triangles, "{file}");
            assert_eq!(report.source_triangles(), source_triangles, "{file}");
            // SOURCES.md: geometry only, no mtllib or usemtl.
            assert!(report.material_libraries.is_empty() && mesh.materials.len() == 1, "{file}");
            assert!(mesh.prim_ids.windows(2).all(|w| w[0] < w[1]), "{file}: prim ids not increasing");
            assert!(mesh.prim_ids.last().is_some_and(|&p| (p as usize) < source_triangles), "{file}");
            if file.starts_with("conference") {
                assert!(report.degenerate_dropped > 50_000, "{report:?}");
            }
            if file.starts_with("sponza") {
                assert_eq!(report.degenerate_dropped, 1);
                let mut text = Vec::new();
                let bytes = std::fs::read(&path).unwrap();
                flate2::read::GzDecoder::new(&bytes[..]).read_to_end(&mut text).unwrap();
                let theirs = tobj_triangles(std::str::from_utf8(&text).unwrap());
                assert_eq!(theirs.len(), source_triangles);
                for (i, &prim) in mesh.prim_ids.iter().enumerate() {
                    assert_eq!(mesh.triangle(i), theirs[prim as usize], "triangle {i}");
                }
            }
        }
    }
}
