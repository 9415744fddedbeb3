//! Re-centring: stored positions are f32 relative to the scene origin (spec §9, `scene.origin`;
//! world = origin + stored, in f64). CAD exports often place parts millions of units from zero,
//! where f32 coordinates are 0.06 to 1 unit apart; subtracting an origin near the model before
//! rounding keeps the precision the input had. Importers compute world positions in f64 and hand
//! them to [`TriangleSink::place`], which subtracts the origin and rounds once.

use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use oocfmt::metadata::Material;

use super::{DropReason, ImportError, InputTriangle, Location, Skipped, TriangleSink};

/// Where the scene origin goes (`oocfmt convert --recentre`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Recentre {
    /// Origin zero: positions are stored as the input gives them, rounded to f32 once.
    #[default]
    None,
    /// Near the centre of the input's bounds ([`auto_origin`]), found by a first pass over the
    /// input that only reads positions.
    Auto,
    /// This origin (finite).
    At([f64; 3]),
}

impl FromStr for Recentre {
    type Err = String;

    fn from_str(s: &str) -> Result<Recentre, String> {
        match s.trim() {
            "none" => return Ok(Recentre::None),
            "auto" => return Ok(Recentre::Auto),
            _ => {}
        }
        let expected = "expected auto, none or X,Y,Z (three finite numbers)";
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let [x, y, z] = parts.as_slice() else {
            return Err(format!("`{s}`: {expected}"));
        };
        let mut origin = [0.0; 3];
        for (slot, word) in origin.iter_mut().zip([x, y, z]) {
            let v: f64 = word
                .parse()
                .map_err(|_| format!("`{word}` is not a number: {expected}"))?;
            if !v.is_finite() {
                return Err(format!("`{word}` is not finite: {expected}"));
            }
            *slot = v;
        }
        Ok(Recentre::At(origin))
    }
}

impl fmt::Display for Recentre {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Recentre::None => f.write_str("none"),
            Recentre::Auto => f.write_str("auto"),
            Recentre::At([x, y, z]) => write!(f, "{x},{y},{z}"),
        }
    }
}

impl Recentre {
    /// Whether finding the origin takes a first pass over the input.
    pub fn needs_scan(&self) -> bool {
        matches!(self, Recentre::Auto)
    }

    /// The origin to store positions relative to. For [`Recentre::Auto`], `scan` must import
    /// every input into the sink it is given: a [`BoundsSink`], which keeps only the bounds of
    /// the positions and tells importers they may skip the rest (`positions_only`).
    pub fn origin<E>(
        &self,
        scan: impl FnOnce(&mut dyn TriangleSink) -> Result<(), E>,
    ) -> Result<[f64; 3], E> {
        match self {
            Recentre::None => Ok([0.0; 3]),
            Recentre::At(origin) => Ok(*origin),
            Recentre::Auto => {
                let mut bounds = BoundsSink::default();
                scan(&mut bounds)?;
                Ok(bounds
                    .bounds()
                    .map_or([0.0; 3], |(lo, hi)| auto_origin(lo, hi)))
            }
        }
    }

    /// Build parameters that record the choice. None without re-centring, so that files
    /// converted without it do not change.
    pub fn params(&self, origin: [f64; 3]) -> Vec<(String, String)> {
        match self {
            Recentre::None => Vec::new(),
            _ => vec![
                ("recentre".into(), self.to_string()),
                (
                    "origin".into(),
                    format!("{},{},{}", origin[0], origin[1], origin[2]),
                ),
            ],
        }
    }
}

/// The largest power of two not above `v` (a positive normal f64).
fn pow2_floor(v: f64) -> f64 {
    f64::from_bits(v.to_bits() & !((1u64 << 52) - 1))
}

/// The origin `--recentre auto` picks for input bounds `lo..hi` (in f64): the centre of the
/// box, rounded to a multiple of a power of two between 1/32 and 1/16 of the box's largest
/// extent. The rounding costs little (stored offsets stay within 17/32 of the extent, so at
/// most one f32 binade more than the best possible) and makes the origin a short binary
/// number, so that `x − origin` is exact in f64 for coordinates of the origin's magnitude and
/// rounding to f32 is the only error. A model already around zero gets origin zero: it stays
/// bit-exact. Non-finite bounds (nothing to centre) give zero too.
pub fn auto_origin(lo: [f64; 3], hi: [f64; 3]) -> [f64; 3] {
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
    let magnitude = lo.iter().chain(&hi).map(|c| c.abs()).fold(0.0, f64::max);
    if !(extent.is_finite() && magnitude.is_normal()) {
        return [0.0; 3];
    }
    let ulp = pow2_floor(magnitude) * f64::EPSILON;
    let fine = extent / 16.0;
    let step = if fine.is_normal() {
        pow2_floor(fine).max(ulp)
    } else {
        ulp
    };
    let origin = [0, 1, 2].map(|a| ((lo[a] / 2.0 + hi[a] / 2.0) / step).round() * step);
    if origin.iter().all(|c| c.is_finite()) {
        origin
    } else {
        [0.0; 3]
    }
}

/// What storing the positions relative to the origin cost, for the convert report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PlacementReport {
    /// The scene origin: world = origin + stored.
    pub origin: [f64; 3],
    /// The largest difference, over every coordinate (per axis, not Euclidean) of every finite
    /// input position, between `origin + stored` (added in f64, as readers and `oocfmt
    /// export` do) and the input's position in f64.
    pub max_abs_error: f64,
    /// The same figure had the positions been stored without an origin (rounded to f32
    /// directly): what re-centring gained.
    pub max_abs_error_without_origin: f64,
}

/// Subtracts the origin from world positions and rounds them to f32, keeping the
/// [`PlacementReport`] figures. Sinks hold one and delegate [`TriangleSink::place`] to it.
#[derive(Clone, Debug, Default)]
pub struct Placement {
    report: PlacementReport,
}

impl Placement {
    /// Places positions relative to `origin` (world coordinates, f64).
    pub fn new(origin: [f64; 3]) -> Placement {
        Placement {
            report: PlacementReport {
                origin,
                ..PlacementReport::default()
            },
        }
    }

    /// The scene origin: world = origin + stored.
    pub fn origin(&self) -> [f64; 3] {
        self.report.origin
    }

    /// The stored (relative, f32) position of the world position `exact`.
    pub fn place(&mut self, exact: [f64; 3]) -> [f32; 3] {
        let r = &mut self.report;
        let mut stored = [0.0f32; 3];
        for (a, s) in stored.iter_mut().enumerate() {
            let (x, o) = (exact[a], r.origin[a]);
            *s = (x - o) as f32;
            if !(x.is_finite() && s.is_finite()) {
                continue;
            }
            let error = (o + f64::from(*s) - x).abs();
            r.max_abs_error = r.max_abs_error.max(error);
            let direct = x as f32;
            if o == 0.0 {
                r.max_abs_error_without_origin = r.max_abs_error_without_origin.max(error);
            } else if direct.is_finite() {
                let error = (f64::from(direct) - x).abs();
                r.max_abs_error_without_origin = r.max_abs_error_without_origin.max(error);
            }
        }
        stored
    }

    /// The origin and the rounding errors over every position placed so far.
    pub fn report(&self) -> PlacementReport {
        self.report
    }
}

/// The sink of the first pass of `--recentre auto`: keeps the f64 bounds of the finite
/// positions placed and nothing else. Warnings, drops and errors under `--strict` are left to
/// the real pass, so they are reported once.
#[derive(Clone, Debug, Default)]
pub struct BoundsSink {
    bounds: Option<([f64; 3], [f64; 3])>,
    materials: u32,
    parts: u32,
}

impl BoundsSink {
    /// The box around every finite position placed, if any was.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        self.bounds
    }
}

impl TriangleSink for BoundsSink {
    fn add_material(&mut self, _material: Material) -> Result<u32, ImportError> {
        let index = self.materials;
        self.materials = self.materials.saturating_add(1);
        Ok(index)
    }

    fn add_part(&mut self, _part: super::PartDef) -> Result<u32, ImportError> {
        let index = self.parts;
        self.parts = self.parts.saturating_add(1);
        Ok(index)
    }

    fn push(&mut self, _triangle: InputTriangle, _at: &Location) -> Result<(), ImportError> {
        Ok(())
    }

    fn reject(&mut self, _reason: DropReason, _at: &Location) -> Result<(), ImportError> {
        Ok(())
    }

    fn skip(&mut self, _what: Skipped, _count: u64) {}

    fn warn(&mut self, _at: &Location, _message: String) {}

    fn begin_file(&mut self, _path: &str) {}

    fn place(&mut self, exact: [f64; 3]) -> [f32; 3] {
        if exact.iter().all(|c| c.is_finite()) {
            let (lo, hi) = self.bounds.get_or_insert((exact, exact));
            for a in 0..3 {
                lo[a] = lo[a].min(exact[a]);
                hi[a] = hi[a].max(exact[a]);
            }
        }
        exact.map(|c| c as f32)
    }

    fn positions_only(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recentre_values_parse_and_bad_ones_say_why() {
        assert_eq!("none".parse(), Ok(Recentre::None));
        assert_eq!(" auto".parse(), Ok(Recentre::Auto));
        assert_eq!("1e7, -2.5 ,0".parse(), Ok(Recentre::At([1e7, -2.5, 0.0])));
        for bad in ["", "centre", "1,2", "1,2,3,4", "1,,3", "a,b,c"] {
            let e = bad.parse::<Recentre>().err().unwrap_or_default();
            assert!(e.contains("expected auto, none or X,Y,Z"), "{bad}: {e}");
        }
        for bad in ["nan,0,0", "0,inf,0", "0,0,-inf", "1e999,0,0"] {
            let e = bad.parse::<Recentre>().err().unwrap_or_default();
            assert!(e.contains("is not finite"), "{bad}: {e}");
        }
        let at = Recentre::At([1e7, -0.5, 3.0]);
        assert_eq!(at.to_string().parse(), Ok(at));
    }

    #[test]
    fn only_recentring_adds_build_parameters() {
        assert!(Recentre::None.params([0.0; 3]).is_empty());
        let p = Recentre::Auto.params([8.0, 0.0, -1.5]);
        assert_eq!(
            p,
            [
                ("recentre".to_string(), "auto".to_string()),
                ("origin".to_string(), "8,0,-1.5".to_string())
            ]
        );
    }

    #[test]
    fn the_auto_origin_is_a_round_number_near_the_centre() {
        // An aircraft 1e7 units out, 60 units long.
        let lo = [9_999_970.25, -12.0, 3_000_000.5];
        let hi = [10_000_030.75, 12.0, 3_000_010.0];
        let o = auto_origin(lo, hi);
        // The extent is 60.5: the step is 2 (between 60.5/32 and 60.5/16).
        assert_eq!(o, [10_000_000.0, 0.0, 3_000_006.0]);
        for a in 0..3 {
            let far = (lo[a] - o[a]).abs().max((hi[a] - o[a]).abs());
            assert!(far <= 60.5 * 17.0 / 32.0, "axis {a}: {far}");
        }
        // A model around zero is left where it is.
        assert_eq!(auto_origin([-1.1, -1.0, -1.2], [1.1, 1.05, 1.2]), [0.0; 3]);
        // One point (no extent): the origin is the point itself.
        assert_eq!(auto_origin([1e7; 3], [1e7; 3]), [1e7; 3]);
        assert_eq!(auto_origin([f64::NAN; 3], [1.0; 3]), [0.0; 3]);
        assert_eq!(auto_origin([-f64::MAX; 3], [f64::MAX; 3]), [0.0; 3]);
        assert_eq!(auto_origin([0.0; 3], [0.0; 3]), [0.0; 3]);
    }

    #[test]
    fn placing_far_positions_relative_to_an_origin_keeps_their_precision() {
        let x = [10_000_000.123_456_7, -7_654_321.012_345, 0.1];
        let mut none = Placement::new([0.0; 3]);
        let direct = none.place(x);
        assert_eq!(direct, x.map(|c| c as f32));
        let r0 = none.report();
        assert_eq!(r0.max_abs_error, r0.max_abs_error_without_origin);
        // f32 spacing at 1e7 is 1: the error is up to half of it.
        assert!(r0.max_abs_error > 0.1 && r0.max_abs_error <= 0.5, "{r0:?}");

        let origin = [10_000_000.0, -7_654_320.0, 0.0];
        let mut shifted = Placement::new(origin);
        let s = shifted.place(x);
        let r = shifted.report();
        for a in 0..3 {
            let back = origin[a] + f64::from(s[a]);
            assert!((back - x[a]).abs() <= r.max_abs_error);
        }
        assert!(r.max_abs_error < 1e-7, "{r:?}");
        assert_eq!(r.max_abs_error_without_origin, r0.max_abs_error);
    }

    #[test]
    fn non_finite_positions_pass_through_without_touching_the_figures() {
        let mut p = Placement::new([5.0; 3]);
        let s = p.place([f64::NAN, f64::INFINITY, 1e300]);
        assert!(s[0].is_nan() && s[1] == f32::INFINITY && s[2] == f32::INFINITY);
        assert_eq!(p.report().max_abs_error, 0.0);
        assert_eq!(p.report().max_abs_error_without_origin, 0.0);
    }

    #[test]
    fn the_bounds_sink_keeps_finite_positions_only() {
        let mut b = BoundsSink::default();
        assert_eq!(b.bounds(), None);
        b.place([1.0, f64::NAN, 0.0]);
        assert_eq!(b.bounds(), None);
        b.place([1.0, 2.0, 3.0]);
        b.place([-1.0, 5.0, 3.0]);
        assert_eq!(b.bounds(), Some(([-1.0, 2.0, 3.0], [1.0, 5.0, 3.0])));
        let origin = Recentre::Auto.origin(|sink| -> Result<(), ImportError> {
            sink.place([1e7, 0.0, 0.0]);
            sink.place([1e7 + 8.0, 1.0, 1.0]);
            Ok(())
        });
        assert_eq!(origin.ok(), Some([1e7 + 4.0, 0.5, 0.5]));
    }
}
