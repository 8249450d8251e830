//! Surface materials: the thesis's fixed-function shader parameters (Tsakok 2008, 4.2.1,
//! Listing 4.7), modelled only as far as a scene needs (no texture or normal maps: no shared
//! scene has them).
//!
//! The thesis stores a shader type beside a union of parameter blocks. Here the type is derived
//! from the parameters ([`Material::shader`]), so a material can never claim to reflect with a
//! zero reflectivity: a reflectivity above zero makes it reflective, a transparency above zero
//! transparent, both make it the transparent-reflective `M_TR`.

use glam::Vec3;

/// The thesis's five shader types (Listing 4.7's `SH_TYPE`). Only the last three spawn
/// secondary rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shader {
    /// `M_D`: diffuse only.
    Diffuse,
    /// `M_S`: diffuse and Phong specular highlights (no secondary rays).
    Specular,
    /// `M_R`: diffuse, specular and a reflection ray.
    Reflective,
    /// `M_T`: diffuse and a refraction ray.
    Transparent,
    /// `M_TR`: diffuse, specular, a reflection and a refraction ray, weighted by Schlick's
    /// Fresnel term.
    TransparentReflective,
}

impl Shader {
    /// The thesis's name of the type (`M_D`, `M_S`, `M_R`, `M_T`, `M_TR`).
    pub fn thesis_name(self) -> &'static str {
        match self {
            Shader::Diffuse => "M_D",
            Shader::Specular => "M_S",
            Shader::Reflective => "M_R",
            Shader::Transparent => "M_T",
            Shader::TransparentReflective => "M_TR",
        }
    }
}

/// A surface material: the thesis's `d_info`, `s_info`, `r_info`, `t_info` and `tr_info`
/// parameters in one record (Listing 4.7).
///
/// Invariants (checked by [`Material::check`]): every field is finite; `diffuse` components,
/// `specular_blend`, `reflectivity` and `transparency` are in `[0, 1]`; `specular_exponent`
/// is at least 0; `ior` is at least 1.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name (from the OBJ `usemtl` or the built-in scene).
    pub name: String,
    /// Diffuse reflectance (linear RGB, each in [0, 1]): `d_info::base`.
    pub diffuse: Vec3,
    /// Phong exponent of the specular highlight: `s_info::exp`.
    pub specular_exponent: f32,
    /// Intensity of the specular highlight, 0 for none: `s_info::blend`.
    pub specular_blend: f32,
    /// Weight of the reflected colour, 0 for none: `r_info::blend`.
    pub reflectivity: f32,
    /// Weight of the refracted colour, 0 for opaque: `t_info::blend`.
    pub transparency: f32,
    /// Index of refraction of the material's inside (outside is 1): `refract_index`.
    pub ior: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            name: "default".into(),
            diffuse: Vec3::splat(0.75),
            specular_exponent: 0.0,
            specular_blend: 0.0,
            reflectivity: 0.0,
            transparency: 0.0,
            ior: 1.0,
        }
    }
}

impl Material {
    /// A diffuse material (`M_D`) of the given colour.
    pub fn diffuse(name: &str, diffuse: Vec3) -> Material {
        Material { name: name.to_string(), diffuse, ..Material::default() }
    }

    /// The shader type these parameters make (Listing 4.7's `type`).
    pub fn shader(&self) -> Shader {
        match (self.reflectivity > 0.0, self.transparency > 0.0) {
            (true, true) => Shader::TransparentReflective,
            (false, true) => Shader::Transparent,
            (true, false) => Shader::Reflective,
            (false, false) if self.specular_blend > 0.0 => Shader::Specular,
            (false, false) => Shader::Diffuse,
        }
    }

    /// Whether shading a hit on this material traces a reflection ray.
    pub fn reflects(&self) -> bool {
        self.reflectivity > 0.0
    }

    /// Whether shading a hit on this material traces a refraction ray.
    pub fn refracts(&self) -> bool {
        self.transparency > 0.0
    }

    /// Checks the invariants, naming the first parameter out of range.
    pub fn check(&self) -> Result<(), String> {
        let unit = |what: &str, v: f32| {
            if v.is_finite() && (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(format!("material '{}': {what} {v} is not in [0, 1]", self.name))
            }
        };
        for (axis, v) in ["red", "green", "blue"].into_iter().zip(self.diffuse.to_array()) {
            unit(&format!("diffuse {axis}"), v)?;
        }
        unit("specular blend", self.specular_blend)?;
        unit("reflectivity", self.reflectivity)?;
        unit("transparency", self.transparency)?;
        if !(self.specular_exponent.is_finite() && self.specular_exponent >= 0.0) {
            return Err(format!(
                "material '{}': specular exponent {} is not a finite number of at least 0",
                self.name, self.specular_exponent
            ));
        }
        if !(self.ior.is_finite() && self.ior >= 1.0) {
            return Err(format!(
                "material '{}': index of refraction {} is not a finite number of at least 1",
                self.name, self.ior
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shader_type_follows_the_parameters() {
        let m = Material::default();
        assert_eq!(m.shader(), Shader::Diffuse);
        let s = Material { specular_blend: 0.5, specular_exponent: 20.0, ..m.clone() };
        assert_eq!(s.shader(), Shader::Specular);
        let r = Material { reflectivity: 0.8, ..s.clone() };
        assert_eq!(r.shader(), Shader::Reflective);
        let t = Material { transparency: 0.9, ior: 1.5, ..m.clone() };
        assert_eq!(t.shader(), Shader::Transparent);
        let tr = Material { transparency: 0.9, ..r.clone() };
        assert_eq!(tr.shader(), Shader::TransparentReflective);
        assert_eq!(tr.shader().thesis_name(), "M_TR");
        assert!(tr.reflects() && tr.refracts() && !m.reflects() && !m.refracts());
    }

    #[test]
    fn check_names_the_bad_parameter() {
        assert!(Material::default().check().is_ok());
        let bad = [
            (Material { diffuse: Vec3::new(0.5, f32::NAN, 0.5), ..Material::default() }, "diffuse green"),
            (Material { reflectivity: -0.1, ..Material::default() }, "reflectivity"),
            (Material { transparency: 1.5, ..Material::default() }, "transparency"),
            (Material { specular_blend: f32::INFINITY, ..Material::default() }, "specular blend"),
            (Material { specular_exponent: -1.0, ..Material::default() }, "specular exponent"),
            (Material { ior: 0.9, ..Material::default() }, "index of refraction"),
            (Material { ior: f32::NAN, ..Material::default() }, "index of refraction"),
        ];
        for (m, what) in bad {
            let e = m.check().unwrap_err();
            assert!(e.contains(what) && e.contains("'default'"), "{e}");
        }
    }
}
