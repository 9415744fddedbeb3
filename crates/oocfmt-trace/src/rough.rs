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

/// Azimuths of the midpoint rule in [`lit_cosine`]: its error stays below 1/512 (the spec's
/// bound) on the brute-force test below.
const AZIMUTHS: usize = 64;

/// The mean Lambert term of the same rough surface (unit mean normal `n`, shade `sigma`) seen
/// from unit direction `v` and lit from unit direction `l` (spec §5.1, L(v, l, σ)): each facet
/// shows in proportion to its cosine to `v` and is as bright as its cosine to `l`. For `l = v`
/// it is [`rough_cosine`]; for σ = 1 it is max(0, n · l). Non-finite results read as 0, so the
/// value always lies in 0 ..= 1.
pub fn lit_cosine(n: [f32; 3], v: [f32; 3], l: [f32; 3], sigma: f32) -> f32 {
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let sigma = if sigma.is_nan() {
        1.0
    } else {
        sigma.clamp(0.0, 1.0)
    };
    let (cv, cl) = (dot(n, v), dot(n, l));
    let value = if sigma >= 1.0 {
        cl
    } else {
        // The tangent basis: t₁ along v's projection (along l's when v is the normal), so
        // that f·v depends on cos φ alone.
        let vt = [0, 1, 2].map(|k| v[k] - cv * n[k]);
        let lt = [0, 1, 2].map(|k| l[k] - cl * n[k]);
        let sv = dot(vt, vt).sqrt();
        let t1 = if sv > 1e-6 { vt.map(|c| c / sv) } else { lt };
        let len1 = dot(t1, t1).sqrt();
        let l1 = if len1 > 0.0 { dot(lt, t1) / len1 } else { 0.0 };
        let l2 = (dot(lt, lt) - l1 * l1).max(0.0).sqrt();
        let sv = if sv > 1e-6 { sv } else { 0.0 };
        let sb = (1.0 - sigma * sigma).max(0.0).sqrt();
        // cos φ and sin φ at the midpoints, by rotating one step at a time.
        let step = std::f32::consts::TAU / AZIMUTHS as f32;
        let (ds, dc) = step.sin_cos();
        let (mut s, mut c) = (0.5 * step).sin_cos();
        let (mut shown, mut lit) = (0.0f32, 0.0f32);
        for _ in 0..AZIMUTHS {
            let fv = sigma * cv + sb * sv * c;
            if fv > 0.0 {
                shown += fv;
                lit += fv * (sigma * cl + sb * (l1 * c + l2 * s)).max(0.0);
            }
            (s, c) = (s * dc + c * ds, c * dc - s * ds);
        }
        if shown > 0.0 {
            lit / shown
        } else {
            0.0
        }
    };
    if value.is_finite() {
        value.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::{lit_cosine, rough_cosine};
    use oocfmt_scenes::rng::Rng;

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

    /// L(v, l, σ) by brute force in f64: `k` facets of the cone around `n`.
    fn lit_by_facets(n: [f64; 3], v: [f64; 3], l: [f64; 3], sigma: f64, k: usize) -> f64 {
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        // Any orthonormal t₁, t₂ completing n.
        let a = if n[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let d = dot(a, n);
        let t1 = [0, 1, 2].map(|i| a[i] - d * n[i]);
        let len = dot(t1, t1).sqrt();
        let t1 = t1.map(|c| c / len);
        let t2 = [
            n[1] * t1[2] - n[2] * t1[1],
            n[2] * t1[0] - n[0] * t1[2],
            n[0] * t1[1] - n[1] * t1[0],
        ];
        let sb = (1.0 - sigma * sigma).sqrt();
        let (mut shown, mut lit) = (0.0, 0.0);
        for i in 0..k {
            let phi = (i as f64 + 0.5) / k as f64 * std::f64::consts::TAU;
            let f = [0, 1, 2].map(|j| sigma * n[j] + sb * (phi.cos() * t1[j] + phi.sin() * t2[j]));
            let fv = dot(f, v);
            if fv > 0.0 {
                shown += fv;
                lit += fv * dot(f, l).max(0.0);
            }
        }
        if shown > 0.0 {
            lit / shown
        } else {
            0.0
        }
    }

    #[test]
    fn the_two_direction_form_equals_the_facets_summed() {
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut worst = 0.0f64;
        for case in 0..400 {
            let n = rng.direction();
            let mut v = rng.direction();
            let nv: f64 = (0..3).map(|k| n[k] * v[k]).sum();
            if nv < 0.0 {
                v = v.map(|c| -c);
            }
            let l = rng.direction();
            let sigma = [0.05, 0.3, 0.6, 0.85, 0.97][case % 5];
            let want = lit_by_facets(n, v, l, sigma, 100_000);
            let f = |a: [f64; 3]| a.map(|c| c as f32);
            let got = f64::from(lit_cosine(f(n), f(v), f(l), sigma as f32));
            worst = worst.max((got - want).abs());
        }
        assert!(worst < 1.0 / 512.0, "the largest error is {worst}");
    }

    #[test]
    fn the_two_direction_form_has_its_known_answers() {
        let n = [0.0, 0.0, 1.0];
        for deg in [0.0f32, 20.0, 45.0, 70.0, 89.0] {
            let (s, c) = deg.to_radians().sin_cos();
            let v = [s, 0.0, c];
            // Lit from the eye: the cone cosine.
            for sigma in [0.2, 0.6, 0.95] {
                let got = lit_cosine(n, v, v, sigma);
                assert!(
                    (got - rough_cosine(c, sigma)).abs() < 1.0 / 512.0,
                    "{deg}° σ {sigma}"
                );
            }
            // Flat: the light's own cosine, whatever the view.
            let l = [0.0, -s, c];
            assert!((lit_cosine(n, v, l, 1.0) - c).abs() < 1e-6);
            assert_eq!(lit_cosine(n, v, [0.0, 0.0, -1.0], 1.0), 0.0);
        }
        // Lit from beside the viewer at the same height above the mean surface, a rough surface
        // is darker than lit from the eye: the facets the viewer sees best face the eye.
        let v = [0.6, 0.0, 0.8];
        let l = [-0.6, 0.0, 0.8];
        assert!(lit_cosine(n, v, l, 0.7) < lit_cosine(n, v, v, 0.7) - 0.02);
        // A light just below the mean surface still lights the facets tilted towards it.
        assert!(lit_cosine(n, [0.0, 0.0, 1.0], [1.0, 0.0, -0.05], 0.5) > 0.1);
    }

    #[test]
    fn it_is_never_out_of_range_nor_nan() {
        let odd = [f32::NAN, 0.0, 1e-30, 1.0, f32::INFINITY];
        for a in odd {
            for b in odd {
                for s in [f32::NAN, -1.0, 0.0, 0.5, 1.0, 2.0] {
                    let l = lit_cosine([a, 0.0, 1.0], [0.0, b, 1.0], [b, a, 0.5], s);
                    assert!((0.0..=1.0).contains(&l), "{a} {b} {s}: {l}");
                }
            }
        }
        for c in [f32::NAN, -1.0, 0.0, 1e-30, 0.5, 1.0, 2.0, f32::INFINITY] {
            for s in [f32::NAN, -1.0, 0.0, 1e-30, 0.5, 1.0, 2.0, f32::NEG_INFINITY] {
                let l = rough_cosine(c, s);
                assert!((0.0..=1.0).contains(&l), "{c} {s}: {l}");
            }
        }
    }
}
