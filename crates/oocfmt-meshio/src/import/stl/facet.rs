//! What ASCII and binary facets share on their way to the sink: placing the corners,
//! triangulating the rare loop of more than three, and counting stored normals that point
//! against the winding (the winding wins; one warning per file says how many).

use crate::import::obj::polygon::{Outcome, Triangulator};
use crate::import::{ImportError, InputTriangle, Location, TriangleSink};

pub(super) struct Facets {
    file: String,
    flipped: u64,
    first_flipped: Option<Location>,
    fans: u64,
    placed: Vec<[f32; 3]>,
    triangulator: Triangulator,
}

impl Facets {
    pub(super) fn new(file: &str) -> Facets {
        Facets {
            file: file.to_string(),
            flipped: 0,
            first_flipped: None,
            fans: 0,
            placed: Vec::new(),
            triangulator: Triangulator::default(),
        }
    }

    /// One facet: its corners (three or more, in f64 as read), its stored normal, its colour
    /// and part.
    pub(super) fn emit(
        &mut self,
        sink: &mut dyn TriangleSink,
        corners: &[[f64; 3]],
        normal: [f64; 3],
        colour: Option<[u8; 4]>,
        part: Option<u32>,
        at: &Location,
    ) -> Result<(), ImportError> {
        self.placed.clear();
        self.placed.extend(corners.iter().map(|&c| sink.place(c)));
        if sink.positions_only() {
            return Ok(());
        }
        if against_winding(corners, normal) {
            self.flipped += 1;
            if self.first_flipped.is_none() {
                self.first_flipped = Some(at.clone());
            }
        }
        let triangle = |positions| InputTriangle {
            colours: colour.map(|c| [c; 3]),
            part,
            ..InputTriangle::new(positions)
        };
        if let [a, b, c] = self.placed[..] {
            return sink.push(triangle([a, b, c]), at);
        }
        if self.triangulator.triangulate(&self.placed) == Outcome::Fallback {
            self.fans += 1;
        }
        for t in self.triangulator.triangles() {
            let positions = t.map(|i| self.placed.get(i).copied().unwrap_or_default());
            sink.push(triangle(positions), at)?;
        }
        Ok(())
    }

    /// The file's summary warnings.
    pub(super) fn finish(&self, sink: &mut dyn TriangleSink) {
        if let Some(first) = &self.first_flipped {
            sink.warn(
                &Location::file(&self.file),
                format!(
                    "{} facets have a stored normal pointing against their winding (the first at \
                     {first}); the winding was kept",
                    self.flipped
                ),
            );
        }
        if self.fans > 0 {
            sink.warn(
                &Location::file(&self.file),
                format!(
                    "{} loops could not be ear-clipped (self-intersecting?) and were \
                     fan-triangulated",
                    self.fans
                ),
            );
        }
    }
}

/// Whether `normal` (finite, not zero) points against the winding of `corners`: a negative
/// dot product with their Newell normal (the cross product of the edges, for a triangle).
fn against_winding(corners: &[[f64; 3]], normal: [f64; 3]) -> bool {
    if !normal.iter().all(|c| c.is_finite()) || normal == [0.0; 3] {
        return false;
    }
    let Some(&o) = corners.first() else {
        return false;
    };
    let rel = |p: &[f64; 3]| [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
    let mut w = [0.0f64; 3];
    for (i, p) in corners.iter().enumerate() {
        let (a, b) = (rel(p), rel(corners.get(i + 1).unwrap_or(&o)));
        w[0] += (a[1] - b[1]) * (a[2] + b[2]);
        w[1] += (a[2] - b[2]) * (a[0] + b[0]);
        w[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let dot = w[0] * normal[0] + w[1] * normal[1] + w[2] * normal[2];
    dot < 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_normal_is_against_the_winding_only_when_it_points_away() {
        let ccw = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(!against_winding(&ccw, [0.0, 0.0, 1.0]));
        assert!(against_winding(&ccw, [0.0, 0.0, -1.0]));
        assert!(against_winding(&ccw, [0.3, 0.0, -0.1]));
        // Perpendicular, zero or not finite: no verdict.
        assert!(!against_winding(&ccw, [1.0, 0.0, 0.0]));
        assert!(!against_winding(&ccw, [0.0; 3]));
        assert!(!against_winding(&ccw, [0.0, 0.0, f64::NAN]));
        // A degenerate winding has no direction to be against.
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!(!against_winding(&line, [0.0, 0.0, -1.0]));
        let quad = [
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
        ];
        assert!(against_winding(&quad, [0.0, 0.0, 1.0]));
    }
}
