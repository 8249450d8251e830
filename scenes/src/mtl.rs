//! Wavefront MTL material libraries, read into the thesis's shader parameters ([`Material`],
//! Tsakok 2008, 4.2.1, Listing 4.7).
//!
//! An OBJ file names its libraries on `mtllib` lines and its faces' materials on `usemtl`
//! lines; [`crate::obj::load_obj`] reads the libraries beside the OBJ file and gives each
//! `usemtl` name the material a library defines for it.
//!
//! # Mapping
//!
//! Only these keys are read; every other key (`Ka`, `Ke`, `Tf`, `sharpness`, the texture maps
//! `map_*`, `bump`, `disp`, `decal`, `refl`, the PBR extensions `Pr`, `Pm`, ...) is skipped
//! silently, as are blank lines and `#` comments (also at the end of a numeric line). Keys are
//! case-sensitive, as in the format's specification (`kd` is not `Kd`).
//!
//! | MTL | [`Material`] field |
//! |---|---|
//! | `newmtl NAME` | starts the material `name` (the rest of the line, trimmed, as `usemtl` reads it) |
//! | `Kd r g b` (or `Kd v`: grey) | `diffuse`; absent: the default grey 0.75 |
//! | `Ks r g b` (or `Ks v`) | its mean `(r + g + b) / 3` is `specular_blend` (every model but 0, 1 and 10) and `reflectivity` (models 3, 5, 7); absent: 0 |
//! | `Ns e` | `specular_exponent`; absent: 0 |
//! | `Ni n` | `ior`; absent: 1 (see below for `Ni` below 1) |
//! | `d a` (or `d -halo a`) | `transparency = 1 - a` under the transparent models |
//! | `Tr t` | `transparency = t` under the transparent models, when no `d` is given (`d` wins: some exporters write `Tr 1` for opaque) |
//! | `illum k` | the shader type, below |
//!
//! `illum` (the illumination model, 0 to 10) picks the thesis's shader type:
//!
//! | `illum` | MTL meaning | shader |
//! |---|---|---|
//! | 0, 1 | colour (and ambient) only | `M_D` (no specular) |
//! | 2 | highlight | `M_S` (`M_D` when `Ks` is 0) |
//! | 3 | ray-traced reflection | `M_R`, reflectivity = mean `Ks` |
//! | 4, 6, 9 | glass, refraction | `M_T`, transparency from `d` / `Tr` |
//! | 5 | Fresnel reflection | `M_R`, reflectivity = mean `Ks` |
//! | 7 | refraction and Fresnel reflection | `M_TR`: transparency from `d` / `Tr`, reflectivity = mean `Ks` (the tracer weights the two by Schlick's Fresnel term) |
//! | 8 | reflection without ray tracing (a reflection map) | `M_S` |
//! | 10 | shadow matte | `M_D` |
//! | absent | | as 2, and transparent (as 4) when `d < 1` or `Tr > 0` |
//!
//! The opacity `d` of the opaque models (0-3, 5, 8, 10) is a blend with what lies behind that
//! no refraction ray models: it is checked but leaves the material opaque. The type that
//! results is always the one [`Material::shader`] derives from the parameters (a zero `Ks`
//! under model 3 gives no reflection, a `d 1` under model 4 no refraction).
//!
//! # Errors
//!
//! [`SceneError::Parse`] naming the `.mtl` file, the line and the material: a malformed
//! number (or the wrong count of them), NaN or infinity, a negative value, a `Kd`, `Ks`, `d`
//! or `Tr` above 1, an `illum` that is not an integer from 0 to 10, a `Kd` / `Ks` in the
//! `spectral` or `xyz` form (not supported), a material key before any `newmtl`, an empty
//! `newmtl` name.
//!
//! `Ni` below 1: many real files write `Ni 1.0` or `Ni 0` on every material, opaque ones
//! included, where it means nothing. So an `Ni` below 1 on an *opaque* material (transparency
//! 0 after the mapping) means "no refraction" and gives `ior` 1; only on a transparent
//! material is it an error (a refraction out of a medium thinner than vacuum).
//!
//! A name defined twice in one library keeps its last definition, in the place of its first.

use std::path::Path;

use glam::Vec3;

use crate::{Material, SceneError};

/// Reads the material library at `path` (see the module docs for the mapping and errors).
pub fn load_mtl(path: &Path) -> Result<Vec<Material>, SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })?;
    parse_mtl(&bytes, path)
}

/// Parses MTL text already in memory into its materials, in the order of their first
/// definition, each passing [`Material::check`]; `origin` is only used in error messages.
/// Never panics, whatever the bytes.
pub fn parse_mtl(text: &[u8], origin: &Path) -> Result<Vec<Material>, SceneError> {
    let err = |line: usize, message: String| SceneError::Parse {
        path: origin.to_path_buf(),
        message: format!("line {line}: {message}"),
    };
    let mut materials: Vec<Material> = Vec::new();
    let mut pending: Option<Pending> = None;
    for (line_no, raw) in text.split(|&b| b == b'\n').enumerate() {
        let line_no = line_no + 1;
        let line = String::from_utf8_lossy(raw);
        let Some(key) = line.split_whitespace().next() else { continue };
        if key == "newmtl" {
            if let Some(done) = pending.take() {
                store(&mut materials, done.finish().map_err(|(l, m)| err(l, m))?);
            }
            let name = line.trim_start().strip_prefix("newmtl").unwrap_or_default().trim();
            if name.is_empty() {
                return Err(err(line_no, "'newmtl' without a material name".to_string()));
            }
            pending = Some(Pending::new(name));
            continue;
        }
        if !KEYS.contains(&key) {
            continue;
        }
        let Some(m) = pending.as_mut() else {
            return Err(err(line_no, format!("'{key}' before any 'newmtl'")));
        };
        // The values: the words after the key, up to a comment.
        let values: Vec<&str> = line.split('#').next().unwrap_or_default().split_whitespace().skip(1).collect();
        m.read(key, &values, line_no).map_err(|message| err(line_no, format!("material '{}': {message}", m.name)))?;
    }
    if let Some(done) = pending.take() {
        store(&mut materials, done.finish().map_err(|(l, m)| err(l, m))?);
    }
    Ok(materials)
}

/// The keys read (module docs); `newmtl` is handled apart.
const KEYS: [&str; 7] = ["Kd", "Ks", "Ns", "Ni", "d", "Tr", "illum"];

/// Adds `material`, replacing an earlier one of the same name in its place.
fn store(materials: &mut Vec<Material>, material: Material) {
    match materials.iter_mut().find(|m| m.name == material.name) {
        Some(old) => *old = material,
        None => materials.push(material),
    }
}

/// The MTL parameters of one material as read, before the mapping.
struct Pending {
    /// The `newmtl` name.
    name: String,
    /// `Kd`.
    kd: Option<Vec3>,
    /// `Ks`.
    ks: Option<Vec3>,
    /// `Ns`.
    ns: Option<f32>,
    /// `Ni` and its line (an `Ni` below 1 is refused at the end, naming it).
    ni: Option<(f32, usize)>,
    /// `d` (opacity).
    d: Option<f32>,
    /// `Tr` (transparency).
    tr: Option<f32>,
    /// `illum`.
    illum: Option<u8>,
}

impl Pending {
    /// A material with no parameters read yet.
    fn new(name: &str) -> Pending {
        Pending { name: name.to_string(), kd: None, ks: None, ns: None, ni: None, d: None, tr: None, illum: None }
    }

    /// Reads the values of one of [`KEYS`] on line `line`.
    fn read(&mut self, key: &str, values: &[&str], line: usize) -> Result<(), String> {
        match key {
            "Kd" => self.kd = Some(colour(key, values)?),
            "Ks" => self.ks = Some(colour(key, values)?),
            "Ns" => self.ns = Some(single(key, values)?),
            "Ni" => self.ni = Some((single(key, values)?, line)),
            "d" => {
                let values = if values.first() == Some(&"-halo") { &values[1..] } else { values };
                self.d = Some(at_most_one(key, single(key, values)?)?);
            }
            "Tr" => self.tr = Some(at_most_one(key, single(key, values)?)?),
            "illum" => {
                let [word] = values else {
                    return Err(format!("'illum' takes one integer, got {} values", values.len()));
                };
                match word.parse::<u8>() {
                    Ok(k) if k <= 10 => self.illum = Some(k),
                    _ => return Err(format!("illum '{word}' is not an illumination model from 0 to 10")),
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The material these parameters map to (module docs), or the line and message of the
    /// `Ni` that a transparent material may not have.
    fn finish(self) -> Result<Material, (usize, String)> {
        // What the `illum` model asks for: (highlight, reflection, refraction).
        let (highlight, reflection, refraction) = match self.illum {
            Some(0 | 1 | 10) => (false, false, false),
            Some(2 | 8) => (true, false, false),
            Some(3 | 5) => (true, true, false),
            Some(4 | 6 | 9) => (true, false, true),
            Some(7) => (true, true, true),
            None => (true, false, true),
            Some(_) => (false, false, false),
        };
        let ks = self.ks.map_or(0.0, |k| (k.x + k.y + k.z) / 3.0);
        let transparency = if refraction { self.d.map(|d| 1.0 - d).or(self.tr).unwrap_or(0.0) } else { 0.0 };
        let ior = match self.ni {
            None => 1.0,
            Some((n, _)) if n >= 1.0 => n,
            Some(_) if transparency == 0.0 => 1.0,
            Some((n, line)) => {
                return Err((
                    line,
                    format!(
                        "material '{}': Ni {n} is below 1 on a transparent material (transparency {transparency})",
                        self.name
                    ),
                ));
            }
        };
        Ok(Material {
            diffuse: self.kd.unwrap_or(Material::default().diffuse),
            specular_exponent: self.ns.unwrap_or(0.0),
            specular_blend: if highlight { ks } else { 0.0 },
            reflectivity: if reflection { ks } else { 0.0 },
            transparency,
            ior,
            name: self.name,
        })
    }
}

/// One finite, non-negative number.
fn number(key: &str, word: &str) -> Result<f32, String> {
    let v: f32 = word.parse().map_err(|_| format!("{key}: '{word}' is not a number"))?;
    if !v.is_finite() {
        return Err(format!("{key}: {word} is not a finite number"));
    }
    if v < 0.0 {
        return Err(format!("{key}: {word} is negative"));
    }
    Ok(v)
}

/// The single number after `key`.
fn single(key: &str, values: &[&str]) -> Result<f32, String> {
    match values {
        [word] => number(key, word),
        _ => Err(format!("'{key}' takes one number, got {} values", values.len())),
    }
}

/// `v` if it is at most 1.
fn at_most_one(key: &str, v: f32) -> Result<f32, String> {
    if v <= 1.0 { Ok(v) } else { Err(format!("{key} {v} is above 1")) }
}

/// An RGB colour with each channel in [0, 1]: three numbers, or one for grey.
fn colour(key: &str, values: &[&str]) -> Result<Vec3, String> {
    if let Some(&form @ ("spectral" | "xyz")) = values.first() {
        return Err(format!("{key} in the '{form}' form is not supported (give r g b)"));
    }
    let rgb = match values {
        [v] => Vec3::splat(number(key, v)?),
        [r, g, b] => Vec3::new(number(key, r)?, number(key, g)?, number(key, b)?),
        _ => return Err(format!("'{key}' takes 3 numbers (or 1 for grey), got {} values", values.len())),
    };
    for (channel, v) in ["red", "green", "blue"].into_iter().zip(rgb.to_array()) {
        if v > 1.0 {
            return Err(format!("{key} {channel} {v} is above 1"));
        }
    }
    Ok(rgb)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Shader;
    use proptest::prelude::*;

    fn parse(text: &str) -> Result<Vec<Material>, SceneError> {
        parse_mtl(text.as_bytes(), Path::new("test.mtl"))
    }

    fn one(text: &str) -> Material {
        let materials = parse(text).unwrap();
        assert_eq!(materials.len(), 1, "{text}");
        materials[0].check().unwrap();
        materials.into_iter().next().unwrap()
    }

    fn error_text(text: &str) -> String {
        match parse(text) {
            Err(e @ SceneError::Parse { .. }) => e.to_string(),
            other => panic!("{text:?}: expected a parse error, got {other:?}"),
        }
    }

    #[test]
    fn each_key_sets_its_field() {
        let m = one("newmtl paint\nKd 0.1 0.2 0.3\nKs 0.3 0.6 0.9\nNs 96\nNi 1.45\nillum 3\n");
        assert_eq!(m.name, "paint");
        assert_eq!(m.diffuse, Vec3::new(0.1, 0.2, 0.3));
        assert!((m.specular_blend - 0.6).abs() < 1e-6 && m.reflectivity == m.specular_blend);
        assert_eq!((m.specular_exponent, m.ior, m.transparency), (96.0, 1.45, 0.0));
        // One number is grey; d and Tr give the transparency of a transparent model.
        assert_eq!(one("newmtl g\nKd 0.4\n").diffuse, Vec3::splat(0.4));
        assert_eq!(one("newmtl g\nKs 0.4\nillum 2\n").specular_blend, 0.4);
        assert_eq!(one("newmtl g\nd 0.25\nillum 4\n").transparency, 0.75);
        assert_eq!(one("newmtl g\nd -halo 0.25\nillum 4\n").transparency, 0.75);
        assert_eq!(one("newmtl g\nTr 0.3\nillum 6\n").transparency, 0.3);
        // d wins over Tr, in either order.
        assert_eq!(one("newmtl g\nTr 1\nd 1\nillum 4\n").transparency, 0.0);
        assert_eq!(one("newmtl g\nd 0.5\nTr 0.9\nillum 4\n").transparency, 0.5);
        // Nothing given: the default material under its name.
        assert_eq!(one("newmtl plain\n"), Material { name: "plain".into(), ..Material::default() });
    }

    #[test]
    fn illum_models_map_to_the_thesis_shaders() {
        let base = "newmtl m\nKd 0.5 0.5 0.5\nKs 0.4 0.4 0.4\nNs 50\nd 0.2\nNi 1.5\n";
        let expect = [
            (0, Shader::Diffuse),
            (1, Shader::Diffuse),
            (2, Shader::Specular),
            (3, Shader::Reflective),
            (4, Shader::Transparent),
            (5, Shader::Reflective),
            (6, Shader::Transparent),
            (7, Shader::TransparentReflective),
            (8, Shader::Specular),
            (9, Shader::Transparent),
            (10, Shader::Diffuse),
        ];
        for (illum, shader) in expect {
            let m = one(&format!("{base}illum {illum}\n"));
            assert_eq!(m.shader(), shader, "illum {illum}");
            let transparent = matches!(shader, Shader::Transparent | Shader::TransparentReflective);
            let expected = if transparent { 0.8 } else { 0.0 };
            assert!((m.transparency - expected).abs() < 1e-6, "illum {illum}: {}", m.transparency);
            let reflective = matches!(shader, Shader::Reflective | Shader::TransparentReflective);
            assert_eq!(m.reflectivity, if reflective { m.specular_blend } else { 0.0 }, "illum {illum}");
            assert_eq!(m.specular_blend > 0.0, !matches!(illum, 0 | 1 | 10), "illum {illum}");
            assert_eq!(m.ior, 1.5);
        }
        // No illum: highlight, and transparent when d says so.
        assert_eq!(one(&base.replace("d 0.2\n", "")).shader(), Shader::Specular);
        assert_eq!(one(base).shader(), Shader::Transparent);
        assert_eq!(one("newmtl m\nTr 0.5\n").shader(), Shader::Transparent);
        // The type follows the parameters: no Ks, no reflection; d 1, no refraction.
        assert_eq!(one("newmtl m\nillum 3\n").shader(), Shader::Diffuse);
        assert_eq!(one("newmtl m\nd 1\nillum 4\n").shader(), Shader::Diffuse);
        assert_eq!(one("newmtl m\nKs 1 1 1\nd 1\nillum 7\n").shader(), Shader::Reflective);
    }

    #[test]
    fn ni_below_one_is_no_refraction_on_opaque_materials_only() {
        for ni in ["0", "0.5", "1.0"] {
            let m = one(&format!("newmtl opaque\nNi {ni}\nd 1\nillum 2\n"));
            assert_eq!(m.ior, 1.0, "Ni {ni}");
            // Opaque because the model ignores d.
            assert_eq!(one(&format!("newmtl opaque\nNi {ni}\nd 0.5\nillum 2\n")).ior, 1.0);
        }
        let e = error_text("newmtl a\nillum 2\n\nnewmtl glass\nillum 4\nNi 0.9\nd 0.5\n");
        assert!(
            e.contains("test.mtl")
                && e.contains("line 6")
                && e.contains("'glass'")
                && e.contains("Ni 0.9")
                && e.contains("transparent"),
            "{e}"
        );
        // Reported at the end of the material, whether the last one or not.
        let e = error_text("newmtl glass\nNi 0\nTr 0.5\nnewmtl b\n");
        assert!(e.contains("line 2") && e.contains("'glass'"), "{e}");
    }

    #[test]
    fn bad_values_name_the_line_and_material() {
        // (input, what the error names)
        let cases: &[(&str, &[&str])] = &[
            ("newmtl m\nKd 0.5 x 0.5\n", &["line 2", "'m'", "'x' is not a number"]),
            ("newmtl m\nKd 0.5 0.5\n", &["line 2", "3 numbers", "got 2"]),
            ("newmtl m\nKd 0.5 0.5 0.5 0.5\n", &["line 2", "got 4"]),
            ("newmtl m\nKd\n", &["line 2", "got 0"]),
            ("newmtl m\n\nKd 1.2 0.5 0.5\n", &["line 3", "'m'", "Kd red 1.2 is above 1"]),
            ("newmtl m\nKd 0.5 0.5 -0.1\n", &["line 2", "negative"]),
            ("newmtl m\nKs 0.5 nan 0.5\n", &["line 2", "Ks", "not a finite number"]),
            ("newmtl m\nKs 2\n", &["line 2", "Ks red 2 is above 1"]),
            ("newmtl m\nKd spectral white.rfl\n", &["line 2", "spectral", "not supported"]),
            ("newmtl m\nKs xyz 0.1 0.2 0.3\n", &["line 2", "xyz"]),
            ("newmtl m\nNs inf\n", &["line 2", "Ns", "not a finite number"]),
            ("newmtl m\nNs -3\n", &["line 2", "negative"]),
            ("newmtl m\nNs 1e39\n", &["line 2", "not a finite number"]),
            ("newmtl m\nNs 1 2\n", &["line 2", "one number"]),
            ("newmtl m\nNi -1.5\n", &["line 2", "negative"]),
            ("newmtl m\nd 1.5\n", &["line 2", "d 1.5 is above 1"]),
            ("newmtl m\nd -halo\n", &["line 2", "got 0"]),
            ("newmtl m\nTr -0.5\n", &["line 2", "negative"]),
            ("newmtl m\nTr 1.01\n", &["line 2", "above 1"]),
            ("newmtl m\nillum 11\n", &["line 2", "illum '11'", "0 to 10"]),
            ("newmtl m\nillum 2.0\n", &["line 2", "illum '2.0'"]),
            ("newmtl m\nillum -1\n", &["line 2", "illum '-1'"]),
            ("newmtl m\nillum\n", &["line 2", "one integer"]),
            ("# header\nKd 1 1 1\nnewmtl m\n", &["line 2", "'Kd' before any 'newmtl'"]),
            ("newmtl a\nnewmtl   \n", &["line 2", "without a material name"]),
        ];
        for (input, names) in cases {
            let e = error_text(input);
            assert!(e.contains("test.mtl") && names.iter().all(|name| e.contains(name)), "{input:?}: {e}");
        }
    }

    #[test]
    fn other_keys_comments_and_line_endings_are_skipped() {
        let text = "# a library\r\nnewmtl Stone Wall \r\n\tKa 0.1 0.1 0.1\r\nKd 0.5 0.4 0.3 # sandstone\r\n\
                    map_Kd textures/stone.png\r\nbump -bm 2 stone_bump.png\r\nrefl -type sphere sky.png\r\n\
                    Ke 9 9 9\r\nTf 1 1 1\r\nPr 0.3\r\nsharpness 60\r\nkd 5 5 5\r\n";
        let m = one(text);
        assert_eq!(m.name, "Stone Wall");
        assert_eq!(m.diffuse, Vec3::new(0.5, 0.4, 0.3));
        assert_eq!(parse("").unwrap(), vec![]);
        assert_eq!(parse("# only a comment\n\n").unwrap(), vec![]);
    }

    #[test]
    fn several_materials_in_order_and_a_redefinition_replaces_in_place() {
        let text = "newmtl a\nKd 1 0 0\nnewmtl b\nKd 0 1 0\nnewmtl a\nKd 0 0 1\n";
        let materials = parse(text).unwrap();
        let names: Vec<&str> = materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(materials[0].diffuse, Vec3::Z);
    }

    #[test]
    fn files_load_and_a_missing_file_is_an_io_error() {
        let dir = std::env::temp_dir().join(format!("scenes-mtl-tests-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("lib.mtl");
        std::fs::write(&path, "newmtl glass\nKs 0.1 0.1 0.1\nd 0.2\nNi 1.5\nillum 7\n").unwrap();
        let materials = load_mtl(&path).unwrap();
        assert_eq!(materials[0].shader(), Shader::TransparentReflective);
        std::fs::write(&path, "newmtl glass\nKd 1 1 7\n").unwrap();
        let e = load_mtl(&path).unwrap_err().to_string();
        assert!(e.contains("lib.mtl") && e.contains("line 2"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(matches!(load_mtl(&path), Err(SceneError::Io { .. })));
    }

    /// Lines made of MTL keys and numbers, nasty ones included, to reach past the key match.
    fn mtl_line() -> impl Strategy<Value = String> {
        let key = prop::sample::select(vec!["newmtl", "Kd", "Ks", "Ns", "Ni", "d", "Tr", "illum", "map_Kd", "#", ""]);
        let word = prop::sample::select(vec![
            "0", "1", "0.5", "2", "-1", "1e39", "nan", "inf", "-halo", "spectral", "x", "10", "11", "1.0", "",
        ]);
        (key, prop::collection::vec(word, 0..5)).prop_map(|(k, w)| format!("{k} {}", w.join(" ")))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        #[test]
        fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
            if let Ok(materials) = parse_mtl(&bytes, Path::new("fuzz.mtl")) {
                for m in materials {
                    prop_assert!(m.check().is_ok(), "{m:?}");
                }
            }
        }

        #[test]
        fn random_key_soup_never_panics_and_accepted_materials_check(
            lines in prop::collection::vec(mtl_line(), 0..20),
        ) {
            let text = lines.join("\n");
            if let Ok(materials) = parse(&text) {
                for m in materials {
                    prop_assert!(m.check().is_ok(), "{text:?}: {m:?}");
                }
            }
        }
    }
}
