//! Deterministic sample patterns: a Hammersley set of n points in the unit square, shifted per
//! pixel by a hashed Cranley–Patterson rotation. The same pixel gets the same samples on every
//! run and thread count; neighbouring pixels get different ones, so the error is noise rather
//! than a pattern. Each coordinate puts one point in each of n equal strata (the first for every
//! n, the second, a van der Corput sequence, when n is a power of two); the rotation moves the
//! strata together, so it keeps that.

/// What one pixel's samples are drawn for: each use gets its own rotation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stream {
    /// Sub-pixel positions of the primary rays.
    Pixel = 1,
    /// Directions of the ambient-occlusion rays of one primary ray.
    Occlusion = 2,
}

/// A 64-bit mix of the pixel, the primary ray and the stream (splitmix64's finaliser).
pub fn hash(x: u32, y: u32, sample: u32, stream: Stream) -> u64 {
    let mut z = (u64::from(x) << 32 | u64::from(y))
        ^ (u64::from(sample) << 8 | stream as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Point `i` of the n-point set rotated by `seed`, both coordinates in [0, 1).
pub fn point(i: u32, n: u32, seed: u64) -> [f64; 2] {
    let shift = [unit(seed >> 40), unit(seed >> 16 & 0xFF_FFFF)];
    let base = [
        (f64::from(i) + 0.5) / f64::from(n.max(1)),
        f64::from(i.reverse_bits()) / 4_294_967_296.0,
    ];
    [0, 1].map(|k| wrap(base[k] + shift[k]))
}

/// The sub-pixel position of primary ray `k` of `n` in pixel (x, y), in [0, 1)²; with one ray
/// the pixel centre.
pub fn pixel_offset(x: u32, y: u32, k: u32, n: u32) -> [f64; 2] {
    if n <= 1 {
        return [0.5, 0.5];
    }
    point(k, n, hash(x, y, 0, Stream::Pixel))
}

/// A direction in the hemisphere around the unit vector `n` with density cos θ / π, from a
/// point of the unit square (Malley's method: uniform on the disc, projected up).
pub fn cosine_hemisphere(n: [f32; 3], u: [f64; 2]) -> [f32; 3] {
    let r = u[0].sqrt();
    let phi = 2.0 * std::f64::consts::PI * u[1];
    let (x, y) = (r * phi.cos(), r * phi.sin());
    let z = (1.0 - u[0]).max(0.0).sqrt();
    let n64 = n.map(f64::from);
    let (t, b) = basis(n64);
    [0, 1, 2].map(|k| (x * t[k] + y * b[k] + z * n64[k]) as f32)
}

/// Two unit vectors completing the unit vector `n` to an orthonormal basis (Duff et al. 2017).
fn basis(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let sign = if n[2] >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n[2]);
    let b = n[0] * n[1] * a;
    (
        [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]],
        [b, sign + n[1] * n[1] * a, -n[1]],
    )
}

/// The low 24 bits as a number in [0, 1).
fn unit(bits: u64) -> f64 {
    (bits & 0xFF_FFFF) as f64 / 16_777_216.0
}

/// x mod 1, kept below 1.
fn wrap(x: f64) -> f64 {
    let f = x - x.floor();
    if f < 1.0 {
        f
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sample_is_the_pixel_centre_and_points_stay_in_the_square() {
        assert_eq!(pixel_offset(3, 9, 0, 1), [0.5, 0.5]);
        for n in [2, 3, 4, 7, 16] {
            for k in 0..n {
                let p = pixel_offset(11, 5, k, n);
                assert!(p.iter().all(|c| (0.0..1.0).contains(c)), "{p:?}");
            }
        }
    }

    #[test]
    fn every_stratum_of_the_first_coordinate_gets_one_point() {
        for n in [3u32, 4, 10] {
            let seed = hash(1, 2, 0, Stream::Occlusion);
            let mut strata: Vec<u32> = (0..n)
                .map(|i| (point(i, n, seed)[0] * f64::from(n)) as u32)
                .collect();
            strata.sort_unstable();
            assert_eq!(strata, (0..n).collect::<Vec<_>>());
        }
    }

    #[test]
    fn hemisphere_directions_are_unit_and_above_the_normal() {
        let normals = [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [0.6, -0.8, 0.0],
            [-0.0, 1.0, -0.0],
        ];
        for n in normals {
            for i in 0..64 {
                let d = cosine_hemisphere(n, point(i, 64, hash(i, 0, 0, Stream::Occlusion)));
                let dot: f32 = (0..3).map(|k| d[k] * n[k]).sum();
                let len: f32 = d.iter().map(|c| c * c).sum::<f32>().sqrt();
                assert!(dot >= 0.0 && (len - 1.0).abs() < 1e-5, "{n:?} {d:?}");
            }
        }
    }

    #[test]
    fn samples_are_deterministic_and_differ_between_pixels() {
        assert_eq!(pixel_offset(7, 8, 2, 4), pixel_offset(7, 8, 2, 4));
        assert_ne!(pixel_offset(7, 8, 2, 4), pixel_offset(8, 7, 2, 4));
        assert_ne!(
            hash(1, 1, 0, Stream::Pixel),
            hash(1, 1, 0, Stream::Occlusion)
        );
    }
}
