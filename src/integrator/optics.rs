//! Optics of specular surfaces: mirror reflection, Snell refraction with Schlick's
//! Fresnel approximation and total internal reflection, and the rule that keeps a
//! scattered direction on the incident side of the true surface.

use glam::Vec3;

/// Reflectance and refracted direction at a dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DielectricScatter {
    /// Fresnel reflectance in [0, 1]; 1 under total internal reflection.
    pub reflectance: f32,
    /// Unit refracted direction; `None` under total internal reflection.
    pub refracted: Option<Vec3>,
}

/// Mirror direction of `d` about the unit normal `n` (either side).
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Snell refraction with Schlick's Fresnel approximation (Schlick 1994).
///
/// `d` is the unit incident direction, `n` the unit normal on the incident side
/// (`d·n <= 0`), `eta_i`/`eta_t` the refractive indices of the incident and the
/// transmitted medium.
///
/// Schlick's formula is symmetric only if it is fed the cosine in the rarer medium:
/// leaving a denser medium it uses the transmitted-side cosine, otherwise it would give
/// a reflectance well below 1 just short of the critical angle where the true Fresnel
/// curve goes to 1 (pbrt-v3 §8.2; Bram de Greve, "Reflections and Refractions in Ray
/// Tracing", 2006). Past the critical angle (`sin²θt > 1`) all energy is reflected.
pub fn dielectric(d: Vec3, n: Vec3, eta_i: f32, eta_t: f32) -> DielectricScatter {
    if eta_i == eta_t {
        // Index-matched media have no interface. Schlick would still return
        // (1 - cos)^5 here, reflecting light off nothing.
        return DielectricScatter {
            reflectance: 0.0,
            refracted: Some(d),
        };
    }
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let eta = eta_i / eta_t;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t > 1.0 {
        return DielectricScatter {
            reflectance: 1.0,
            refracted: None,
        };
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let refracted = (eta * d + (eta * cos_i - cos_t) * n).normalize();
    let r0 = ((eta_i - eta_t) / (eta_i + eta_t)).powi(2);
    let cos = if eta_i > eta_t { cos_t } else { cos_i };
    let reflectance = (r0 + (1.0 - r0) * (1.0 - cos).powi(5)).clamp(0.0, 1.0);
    DielectricScatter {
        reflectance,
        refracted: Some(refracted),
    }
}

/// `dir` if it leaves on the incident side of the true surface (`n_geometric`), else
/// the fallback computed from the geometric normal: a shading normal must never send a
/// reflection into the surface.
#[inline]
pub(crate) fn scatter_dir(dir: Vec3, n_geometric: Vec3, fallback: impl FnOnce() -> Vec3) -> Vec3 {
    if dir.dot(n_geometric) > 0.0 {
        dir
    } else {
        fallback()
    }
}
