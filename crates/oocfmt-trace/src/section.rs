//! The section plane: a plane that cuts the model open, so a person can look inside it
//! (`render --section`, the viewer's section control). It keeps the half-space its normal
//! points into, `normal · p ≥ offset` (world coordinates), and clips the primary rays: a ray
//! sees only the stretch of itself inside that half-space, from where it crosses the plane
//! into it (or its origin, when that is kept) to where it leaves it; a ray that never enters
//! it shows the background. Shadow and ambient-occlusion rays are not clipped: the cut changes
//! what is seen, not how the kept surfaces are lit, so a section never lets light leak into a
//! closed model and lit images of a cut stay comparable with the whole model's.
//!
//! A clipped ray is traced from the point where it enters the kept half-space
//! ([`Clip::ray`]), so the tracer needs no lower bound on its walk; its LOD distances then
//! count from that point, which can only pick finer detail than the pixels of error ask for,
//! never coarser.

use serde::{Deserialize, Serialize};

use crate::error::TraceError;
use crate::intersect::Ray;

/// A section plane in world coordinates: keeps the points `p` with `normal · p ≥ offset`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Section {
    /// The plane's unit normal, pointing into the kept half-space.
    pub normal: [f64; 3],
    /// The plane's signed distance from the world origin along `normal`.
    pub offset: f64,
}

/// What a section leaves of one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Clip {
    /// The whole ray is kept.
    Whole,
    /// Nothing of the ray is kept: it shows the background.
    Empty,
    /// The ray is kept from `start` to `end` (distances in multiples of its direction; `end`
    /// may be infinite).
    Span {
        /// Where the ray enters the kept half-space (0: its origin is kept).
        start: f32,
        /// Where it leaves it (+inf: never).
        end: f32,
    },
}

impl Clip {
    /// The ray to trace for the kept stretch of `ray`: `ray` itself, or one from the point
    /// where it enters the kept half-space. None when nothing is kept. Hits along it are at
    /// [`Clip::start`] less than along `ray`.
    pub fn ray(&self, ray: &Ray) -> Option<Ray> {
        match *self {
            Clip::Whole => Some(*ray),
            Clip::Empty => None,
            Clip::Span { start, .. } if start > 0.0 => {
                let org = [0, 1, 2].map(|k| ray.org[k] + start * ray.dir[k]);
                Some(Ray::new(org, ray.dir))
            }
            Clip::Span { .. } => Some(*ray),
        }
    }

    /// How far along the original ray the traced one ([`Clip::ray`]) starts.
    pub fn start(&self) -> f32 {
        match *self {
            Clip::Span { start, .. } => start,
            _ => 0.0,
        }
    }

    /// The farthest a hit along the traced ray ([`Clip::ray`]) may be and still be kept.
    pub fn limit(&self) -> f32 {
        match *self {
            Clip::Span { start, end } => end - start,
            Clip::Whole => f32::INFINITY,
            Clip::Empty => f32::NEG_INFINITY,
        }
    }
}

impl Section {
    /// The plane `normal · p = offset`, keeping the side `normal` points to; `normal` is
    /// normalised (with `offset` scaled alike). An error for a zero or non-finite normal or a
    /// non-finite offset.
    pub fn new(normal: [f64; 3], offset: f64) -> Result<Section, TraceError> {
        let len = normal.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(len.is_finite() && len > 0.0 && offset.is_finite()) {
            return Err(TraceError::Options(format!(
                "--section: normal {normal:?} and offset {offset} do not make a plane \
                 (expected a finite non-zero normal and a finite offset)"
            )));
        }
        Ok(Section {
            normal: normal.map(|c| c / len),
            offset: offset / len,
        })
    }

    /// The plane `p[axis] = at` (axis 0, 1, 2: x, y, z), keeping `p[axis] ≥ at`.
    pub fn axis(axis: usize, at: f64) -> Result<Section, TraceError> {
        let mut normal = [0.0; 3];
        match normal.get_mut(axis) {
            Some(c) => *c = 1.0,
            None => {
                return Err(TraceError::Options(format!(
                    "--section: axis {axis} (expected 0, 1 or 2)"
                )))
            }
        }
        Section::new(normal, at)
    }

    /// The plane through `point` with normal `normal`, keeping the side `normal` points to.
    pub fn through(point: [f64; 3], normal: [f64; 3]) -> Result<Section, TraceError> {
        let offset = (0..3).map(|k| point[k] * normal[k]).sum::<f64>();
        if !offset.is_finite() {
            return Err(TraceError::Options(format!(
                "--section: point {point:?} is not finite"
            )));
        }
        Section::new(normal, offset)
    }

    /// The same plane keeping the other side.
    pub fn flipped(self) -> Section {
        Section {
            normal: self.normal.map(|c| -c),
            offset: -self.offset,
        }
    }

    /// Whether the world point `p` is on the kept side (on the plane counts as kept).
    pub fn keeps(&self, p: [f64; 3]) -> bool {
        self.distance(p) >= 0.0
    }

    /// The signed distance of world point `p` from the plane, positive on the kept side.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        (0..3).map(|k| self.normal[k] * p[k]).sum::<f64>() - self.offset
    }

    /// Parses `AXIS=VALUE` (AXIS `x`, `y` or `z` keeps the coordinate ≥ VALUE, `-x`, `-y`
    /// or `-z` keeps it ≤ VALUE) or `X,Y,Z,NX,NY,NZ` (through the point, keeping the side
    /// the normal points to). The error says what is wrong with `text`.
    pub fn parse(text: &str) -> Result<Section, String> {
        let bad = |why: &str| format!("--section {text}: {why}");
        let number = |s: &str| {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(&format!("{s:?} is not a finite number")))
        };
        if let Some((axis, value)) = text.split_once('=') {
            let (flip, name) = match axis.trim().strip_prefix('-') {
                Some(n) => (true, n),
                None => (false, axis.trim()),
            };
            let k = match name {
                "x" | "X" => 0,
                "y" | "Y" => 1,
                "z" | "Z" => 2,
                _ => return Err(bad("expected AXIS=VALUE with AXIS x, y, z, -x, -y or -z")),
            };
            let s = Section::axis(k, number(value)?).map_err(|e| bad(&e.to_string()))?;
            return Ok(if flip { s.flipped() } else { s });
        }
        let parts: Vec<&str> = text.split(',').collect();
        let [x, y, z, nx, ny, nz] = parts.as_slice() else {
            return Err(bad("expected AXIS=VALUE or X,Y,Z,NX,NY,NZ"));
        };
        let point = [number(x)?, number(y)?, number(z)?];
        let normal = [number(nx)?, number(ny)?, number(nz)?];
        Section::through(point, normal).map_err(|_| bad("the normal is zero"))
    }

    /// The same plane in stored coordinates, for a container whose world coordinates are its
    /// stored ones plus `origin`.
    pub fn in_stored(&self, origin: [f64; 3]) -> Section {
        Section {
            normal: self.normal,
            offset: self.offset - (0..3).map(|k| self.normal[k] * origin[k]).sum::<f64>(),
        }
    }

    /// What this plane (in the ray's coordinates) leaves of `ray`. Worked out in f64: the
    /// crossing of a ray nearly parallel to the plane is far and must not round to a wrong
    /// side.
    pub fn clip(&self, ray: &Ray) -> Clip {
        let org = ray.org.map(f64::from);
        let dir = ray.dir.map(f64::from);
        let s0 = self.distance(org);
        let rate = (0..3).map(|k| self.normal[k] * dir[k]).sum::<f64>();
        if s0 >= 0.0 {
            if rate >= 0.0 {
                return Clip::Whole;
            }
            return Clip::Span {
                start: 0.0,
                end: (s0 / -rate) as f32,
            };
        }
        if rate <= 0.0 {
            return Clip::Empty;
        }
        Clip::Span {
            start: (-s0 / rate) as f32,
            end: f32::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_takes_axes_flips_and_points_and_refuses_the_rest() -> Result<(), String> {
        let s = Section::parse("x=1.5")?;
        assert_eq!(
            s,
            Section {
                normal: [1.0, 0.0, 0.0],
                offset: 1.5
            }
        );
        let s = Section::parse("-z=2")?;
        assert_eq!(
            s,
            Section {
                normal: [0.0, 0.0, -1.0],
                offset: -2.0
            }
        );
        assert!(s.keeps([0.0, 0.0, 1.0]) && !s.keeps([0.0, 0.0, 3.0]));
        let s = Section::parse("0,2,0,0,2,0")?;
        assert_eq!(
            s,
            Section {
                normal: [0.0, 1.0, 0.0],
                offset: 2.0
            }
        );
        for bad in [
            "",
            "w=1",
            "x=",
            "x=nan",
            "1,2,3",
            "0,0,0,0,0,0",
            "1,2,3,a,0,0",
            "x=inf",
        ] {
            let e = Section::parse(bad).err().ok_or(format!("{bad:?} parsed"))?;
            assert!(e.starts_with(&format!("--section {bad}:")), "{e}");
        }
        Ok(())
    }

    #[test]
    fn clip_keeps_the_stretch_inside_the_kept_half_space() {
        let s = Section {
            normal: [1.0, 0.0, 0.0],
            offset: 2.0,
        };
        // From the cut side towards the plane: kept from the crossing on.
        let c = s.clip(&Ray::new([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]));
        assert_eq!(
            c,
            Clip::Span {
                start: 2.0,
                end: f32::INFINITY
            }
        );
        // From the cut side away from it, or parallel to it: nothing.
        assert_eq!(s.clip(&Ray::new([0.0; 3], [-1.0, 0.0, 0.0])), Clip::Empty);
        assert_eq!(s.clip(&Ray::new([0.0; 3], [0.0, 1.0, 0.0])), Clip::Empty);
        // From the kept side away from it: all; towards it: up to the crossing.
        assert_eq!(
            s.clip(&Ray::new([3.0, 0.0, 0.0], [1.0, 0.0, 0.0])),
            Clip::Whole
        );
        let c = s.clip(&Ray::new([6.0, 0.0, 0.0], [-2.0, 0.0, 0.0]));
        assert_eq!(
            c,
            Clip::Span {
                start: 0.0,
                end: 2.0
            }
        );
        assert_eq!(c.limit(), 2.0);
        // The traced ray starts on the plane, its hits `start` nearer.
        let c = s.clip(&Ray::new([0.0, 1.0, 0.0], [0.5, 0.0, 0.0]));
        let r = c.ray(&Ray::new([0.0, 1.0, 0.0], [0.5, 0.0, 0.0]));
        assert_eq!(r.map(|r| r.org), Some([2.0, 1.0, 0.0]));
        assert_eq!(c.start(), 4.0);
        // Stored coordinates: the world plane x = 2 is x = 1 in a file of origin (1, 0, 0).
        assert_eq!(s.in_stored([1.0, 5.0, 0.0]).offset, 1.0);
    }
}
