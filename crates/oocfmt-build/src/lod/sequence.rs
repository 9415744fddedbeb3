//! The points where a LOD node's rays cross a face: the first two dimensions of the Sobol
//! sequence (a (0, 2)-sequence: every dyadic box of area 1/n holds one of the first n points),
//! Owen-scrambled with a seed per face (the hash-based nested uniform scramble of Burley 2020).
//! An unscrambled low-discrepancy set has a lattice a regular part can alias with: the first
//! 2^k Halton points share one phase modulo 2^-k, so a ribbed plate or a row of bolts of that
//! pitch was seen as fully covered or not at all. Scrambled, the points keep their
//! stratification (a pitch coarser than their spacing is measured exactly) and are uniformly
//! random within it (a finer one is measured without bias). The seed is a function of the face
//! and its cell only, so the result does not depend on the order nodes are sampled in.

/// Point `i` (from 0) of the sequence scrambled with `seed`, in `[0, 1)²`.
pub fn point(i: u64, seed: u64) -> [f64; 2] {
    let i = i as u32;
    let [s0, s1] = [seed as u32, (seed >> 32) as u32];
    let x = owen(i.reverse_bits(), s0);
    let y = owen(sobol_second(i), s1 ^ 0x9e37_79b9);
    [x, y].map(|v| f64::from(v) / 4_294_967_296.0)
}

/// The seed of face `face` of the cell `lo ..= hi` (the cell's f32 bits, mixed).
pub fn seed(face: usize, lo: [f32; 3], hi: [f32; 3]) -> u64 {
    lo.iter()
        .chain(&hi)
        .fold(face as u64 ^ 0x5851_f42d_4c95_7f2d, |h, c| {
            mix(h ^ u64::from(c.to_bits()))
        })
}

/// SplitMix64's finaliser.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The second Sobol dimension of index `i`, as a 32-bit fraction (direction numbers
/// v₁ = 2³¹, vₖ₊₁ = vₖ ^ (vₖ >> 1)).
fn sobol_second(mut i: u32) -> u32 {
    let (mut v, mut out) = (1u32 << 31, 0u32);
    while i != 0 {
        if i & 1 != 0 {
            out ^= v;
        }
        i >>= 1;
        v ^= v >> 1;
    }
    out
}

/// Nested uniform (Owen) scrambling of a 32-bit fraction: a bit is flipped by a hash of the
/// bits above it (Laine and Karras' permutation on the reversed bits).
fn owen(x: u32, seed: u32) -> u32 {
    let mut v = x.reverse_bits();
    v = v.wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50_b47c);
    v ^= v.wrapping_mul(0xb82f_1e52);
    v ^= v.wrapping_mul(0xc7af_e638);
    v ^= v.wrapping_mul(0x8d22_f6e6);
    v.reverse_bits()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_dyadic_box_gets_its_point() {
        // 64 points over an 8 × 8 grid (and 4 × 16, 16 × 4): one point per box.
        for seed in [0, 1, 0xdead_beef_u64 << 20] {
            for (nx, ny) in [(8usize, 8usize), (4, 16), (16, 4), (64, 1), (1, 64)] {
                let mut boxes = vec![0u32; nx * ny];
                for i in 0..64 {
                    let [x, y] = point(i, seed);
                    assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                    boxes[(x * nx as f64) as usize + nx * (y * ny as f64) as usize] += 1;
                }
                assert!(
                    boxes.iter().all(|&c| c == 1),
                    "{nx}x{ny} seed {seed}: {boxes:?}"
                );
            }
        }
    }

    #[test]
    fn a_comb_is_seen_half_covered_at_every_pitch() {
        for pitch in [2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0] {
            for n in [16u64, 64] {
                let (mut sum, mut worst) = (0.0, 0.0f64);
                let seeds = 200;
                for s in 0..seeds {
                    let seed = mix(s);
                    let hits = (0..n)
                        .filter(|&i| (point(i, seed)[0] * pitch).fract() < 0.5)
                        .count();
                    let share = hits as f64 / n as f64;
                    sum += share;
                    worst = worst.max((share - 0.5).abs());
                }
                let mean = sum / f64::from(seeds as u32);
                // Pitches the points resolve are measured exactly; finer ones without bias.
                if (n as f64) >= 2.0 * pitch {
                    assert_eq!(worst, 0.0, "pitch 1/{pitch}, {n} points");
                } else {
                    assert!(
                        (mean - 0.5).abs() < 0.03,
                        "pitch 1/{pitch}, {n} points: {mean}"
                    );
                }
            }
        }
    }

    #[test]
    fn seeds_differ_by_face_and_cell() {
        let (lo, hi) = ([0.0f32; 3], [1.0f32; 3]);
        assert_ne!(seed(0, lo, hi), seed(1, lo, hi));
        assert_ne!(seed(0, lo, hi), seed(0, lo, [1.0, 1.0, 2.0]));
        assert_eq!(seed(3, lo, hi), seed(3, lo, hi));
    }
}
