//! What a scene uses, so that it pays only for that.

/// What a scene contains, computed once at load. The pipeline is configured from this
/// so that a scene pays only for what it uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Features {
    pub triangles: bool,
    pub spheres: bool,
    pub shading_normals: bool,
    pub diffuse: bool,
    pub specular: bool,
    pub mirror: bool,
    pub glass: bool,
    pub textures: bool,
    pub emission: bool,
    pub point_lights: bool,
    pub directional_lights: bool,
    /// Quad, disk or sphere lights: soft shadows, `shadow` samples per shading point.
    pub area_lights: bool,
    /// A used material has a `glossy` lobe.
    pub glossy: bool,
    /// A used dielectric blurs its refracted ray.
    pub translucency: bool,
    /// The camera has a lens (`aperture` > 0): lens samples are drawn.
    pub depth_of_field: bool,
    /// A non-black `[environment]`: it lights lit surfaces through `environment`
    /// samples per shading point (shadow rays to infinity).
    pub environment: bool,
    /// The shutter is open over an interval and something (geometry or the eye)
    /// moves: shutter times are drawn.
    pub motion: bool,
}

impl Features {
    /// Names of the features present, for stats and logs.
    pub fn names(&self) -> Vec<&'static str> {
        let all = [
            (self.triangles, "triangles"),
            (self.spheres, "spheres"),
            (self.shading_normals, "shading_normals"),
            (self.diffuse, "diffuse"),
            (self.specular, "specular"),
            (self.mirror, "mirror"),
            (self.glass, "glass"),
            (self.textures, "textures"),
            (self.emission, "emission"),
            (self.point_lights, "point_lights"),
            (self.directional_lights, "directional_lights"),
            (self.area_lights, "area_lights"),
            (self.glossy, "glossy"),
            (self.translucency, "translucency"),
            (self.depth_of_field, "depth_of_field"),
            (self.environment, "environment"),
            (self.motion, "motion"),
        ];
        all.iter().filter(|(on, _)| *on).map(|(_, n)| *n).collect()
    }
}
