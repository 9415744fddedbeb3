//! The Lambert term of a rough LOD sample: what a footprint whose normals disagree (shade
//! σ < 1, spec §5.1) looks like on average, seen and lit from one direction.
//!
//! The model is a surface of facets tilted by β = acos σ from the sample's normal and spread
//! evenly in azimuth (a cone of normals: V-grooves in every orientation, as a rough surface
//! with no preferred direction has). A facet shows in proportion to its projected area and is
//! as bright as its cosine, and facets turned away from the viewer do not show. A single
//! V-groove across the view would be its brightest orientation: on the measurements of
//! `docs/notes/2026-12-02-lod-error-bounds.md` it made LOD images too bright.

/// The mean Lambert term of a rough surface of shade `sigma` (spec §5.1) seen and lit along
/// one direction at cosine `cos` to its mean normal. It is σ head-on and `cos` itself for
/// σ = 1 (a flat surface); NaN inputs read as 1, and the result lies in 0 ..= 1.
///
/// With A = σ cos θ and B = sin β sin θ a facet at azimuth φ has cosine A + B cos φ. When
/// A ≥ B every facet faces the viewer and the projected-area-weighted mean of the cosines is
/// A + B²/(2A); otherwise only the facets with |φ| < φ₀ = acos(−A/B) show, and the mean is the
/// ratio of the integrals of (A + B cos φ)² and of A + B cos φ over them.
pub fn rough_cosine(cos: f32, sigma: f32) -> f32 {
    let cos = if cos.is_nan() {
        1.0
    } else {
        cos.clamp(0.0, 1.0)
    };
    let sigma = if sigma.is_nan() {
        1.0
    } else {
        sigma.clamp(0.0, 1.0)
    };
    if sigma >= 1.0 {
        return cos;
    }
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let sin_b = (1.0 - sigma * sigma).max(0.0).sqrt();
    let (a, b) = (sigma * cos, sin_b * sin);
    let l = if a >= b {
        if a > 0.0 {
            a + b * b / (2.0 * a)
        } else {
            0.0
        }
    } else {
        let phi = (-a / b).clamp(-1.0, 1.0).acos();
        let (s, c) = phi.sin_cos();
        let shown = a * phi + b * s;
        let squared = a * a * phi + 2.0 * a * b * s + b * b * (phi + s * c) / 2.0;
        if shown > 0.0 {
            squared / shown
        } else {
            0.0
        }
    };
    l.clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::rough_cosine;

    /// The model's mean by brute force: the facets of the cone at `n` azimuths, in f64.
    fn by_facets(cos: f64, sigma: f64, n: usize) -> f64 {
        let (sin, sin_b) = ((1.0 - cos * cos).sqrt(), (1.0 - sigma * sigma).sqrt());
        let (mut shown, mut squared) = (0.0, 0.0);
        for k in 0..n {
            let phi = (k as f64 + 0.5) / n as f64 * std::f64::consts::TAU;
            let f = sigma * cos + sin_b * sin * phi.cos();
            if f > 0.0 {
                shown += f;
                squared += f * f;
            }
        }
        if shown > 0.0 {
            squared / shown
        } else {
            0.0
        }
    }

    #[test]
    fn the_closed_form_equals_the_facets_summed() {
        for s in [0.05, 0.3, 0.5, 0.71, 0.9, 0.99] {
            for deg in [0.0, 10.0, 30.0, 45.0, 60.0, 75.0, 85.0, 89.0, 90.0] {
                let c = f64::to_radians(deg).cos();
                let want = by_facets(c, s, 200_000);
                let got = f64::from(rough_cosine(c as f32, s as f32));
                assert!(
                    (got - want).abs() < 2e-4,
                    "σ {s}, θ {deg}°: {got} against {want}"
                );
            }
        }
    }

    #[test]
    fn it_has_its_known_answers() {
        // Flat: the cosine itself. Head-on: σ.
        for c in [0.0, 0.3, 0.7, 1.0] {
            assert!((rough_cosine(c, 1.0) - c).abs() < 1e-6);
        }
        for s in [0.2, 0.5, 0.9] {
            assert!((rough_cosine(1.0, s) - s).abs() < 1e-6);
        }
        // β = 30°, θ = 45°: every facet in view, A + B²/(2A) = 7 / (8 √1.5).
        let (b, t) = (30f32.to_radians(), 45f32.to_radians());
        let want = 7.0 / (8.0 * 1.5f32.sqrt());
        assert!((rough_cosine(t.cos(), b.cos()) - want).abs() < 1e-5);
        // Grazing: half the cone shows, with mean (π/4) sin β.
        let grazing = rough_cosine(0.0, b.cos());
        assert!((grazing - std::f32::consts::FRAC_PI_4 * b.sin()).abs() < 1e-5);
        // Continuous where the first facets turn away (θ + β = 90°).
        let edge = 60f32.to_radians();
        let (lo, hi) = (edge - 1e-3, edge + 1e-3);
        assert!((rough_cosine(lo.cos(), b.cos()) - rough_cosine(hi.cos(), b.cos())).abs() < 1e-2);
    }

    #[test]
    fn it_is_darker_than_one_groove_across_the_view() {
        // The V-groove across the view, (cos²θ cos²β + sin²θ sin²β) / (cos θ cos β) while
        // θ + β ≤ 90°, is the cone's brightest orientation.
        let (b, t) = (35f32.to_radians(), 40f32.to_radians());
        let groove =
            ((t.cos() * b.cos()).powi(2) + (t.sin() * b.sin()).powi(2)) / (t.cos() * b.cos());
        let cone = rough_cosine(t.cos(), b.cos());
        assert!(cone < groove - 0.05, "{cone} against {groove}");
    }

    #[test]
    fn it_is_never_out_of_range_nor_nan() {
        for c in [f32::NAN, -1.0, 0.0, 1e-30, 0.5, 1.0, 2.0, f32::INFINITY] {
            for s in [f32::NAN, -1.0, 0.0, 1e-30, 0.5, 1.0, 2.0, f32::NEG_INFINITY] {
                let l = rough_cosine(c, s);
                assert!((0.0..=1.0).contains(&l), "{c} {s}: {l}");
            }
        }
    }
}
