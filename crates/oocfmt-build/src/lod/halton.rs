//! Halton points in the unit square (bases 2 and 3), shifted by a fixed irrational offset
//! (a Cranley–Patterson rotation) so that no sample lands exactly on the half and third grid
//! lines where axis-aligned models put their edges and the tree its splits.

/// The radical inverse of `i` in `base`: its digits mirrored behind the point.
pub fn radical_inverse(mut i: u64, base: u64) -> f64 {
    let inv = 1.0 / base as f64;
    let (mut x, mut scale) = (0.0, inv);
    while i > 0 {
        x += (i % base) as f64 * scale;
        i /= base;
        scale *= inv;
    }
    x
}

/// The rotation: fractional parts of √2 and √3 (no short binary or ternary expansion).
const SHIFT: [f64; 2] = [0.414_213_562_373_095_1, 0.732_050_807_568_877_3];

/// Point `i` (from 0) of the shifted Halton sequence, in `[0, 1)²`.
pub fn point(i: u64) -> [f64; 2] {
    match TABLE.get(i as usize) {
        Some(&p) => p,
        None => compute(i),
    }
}

fn compute(i: u64) -> [f64; 2] {
    // Index 0 of the plain sequence is the corner (0, 0); start at 1.
    let j = i + 1;
    [
        (radical_inverse(j, 2) + SHIFT[0]).fract(),
        (radical_inverse(j, 3) + SHIFT[1]).fract(),
    ]
}

/// The first points, as every LOD node uses them: the digit loops cost more than a ray test.
static TABLE: std::sync::LazyLock<Vec<[f64; 2]>> =
    std::sync::LazyLock::new(|| (0..TABLE_LEN).map(compute).collect());
const TABLE_LEN: u64 = 256;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radical_inverses_mirror_the_digits() {
        assert_eq!(radical_inverse(1, 2), 0.5);
        assert_eq!(radical_inverse(6, 2), 0.375);
        assert_eq!(radical_inverse(1, 3), 1.0 / 3.0);
        assert_eq!(radical_inverse(5, 3), 2.0 / 3.0 + 1.0 / 9.0);
    }

    #[test]
    fn points_cover_the_square_evenly() {
        // 64 points: every cell of a 4 × 4 grid gets some, none gets many.
        let mut cells = [0u32; 16];
        for i in 0..64 {
            let [x, y] = point(i);
            assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
            cells[(x * 4.0) as usize + 4 * (y * 4.0) as usize] += 1;
        }
        assert!(cells.iter().all(|&c| (2..=6).contains(&c)), "{cells:?}");
    }
}
