//! Origins for secondary rays that cannot re-hit the surface they leave.
//!
//! - A triangle hit's point is rebuilt from its barycentric weights and the triangle's vertices
//!   (not `org + t·dir`, whose error grows with t), with pbrt's bound (Pharr, Jakob and
//!   Humphreys, 3rd edition, §3.9): each coordinate of Σ bᵢ pᵢ computed in f32 lies within
//!   γ(7)·Σ |bᵢ pᵢ| of the exact point of the triangle. The origin is pushed along the geometric
//!   normal, to the side the new ray leaves through, by the extent of that error box along the
//!   normal, plus a bound of the ray/triangle kernel's own rounding: the watertight kernel has
//!   no lower limit on t (pbrt's has), so the origin must sit far enough from the plane that
//!   the sign of t comes out right, γ([`KERNEL_GAMMA`]) times the distance to the farthest
//!   vertex. Each coordinate is then rounded one more ulp away from the surface.
//! - A voxel or proxy stands for everything in its cell: Áfra (2012) §6.2 widens the threshold
//!   by the voxel's diameter. The hit p lies on the cell's boundary (within the traversal's
//!   positional tolerance), so the cell lies within 2r of p. The origin moves 2r (plus that
//!   tolerance) along the voxel's normal g, to the side the ray leaves through: every point x of
//!   the ray then has (x − p)·g > 2r, so the ray never enters the cell again. Moving along the
//!   normal rather than along the ray keeps the origin on the viewer's side of the surface: a
//!   shadow ray from the inside of a closed mesh still has to cross its wall.
//! - An R-LOD knows more: its triangles lie within its deviation δ of the plane, and p is on
//!   the plane. The origin moves δ (plus the tolerance) along the plane's normal, so the ray
//!   clears every triangle the plane stands for, yet still meets the walls around it that
//!   shade it. Moving 2r would skip those too: LOD shadows came out too bright
//!   (docs/notes/2026-12-05-shadow-ray-offsets.md).

use crate::intersect::Ray;
use crate::traverse::{Hit, Surface};

/// γ(n) of the kernel's rounding bound; the self-intersection test of
/// `tests/trace/secondary.rs` (random triangles from 1e-8 to 1e8, rays in both hemispheres) finds no
/// re-hit with γ(1) already, and this keeps a margin of four.
pub const KERNEL_GAMMA: u32 = 4;

/// Relative positional slack of a cell hit: above the traversal's tolerance (4e-6 of the
/// scene's or the origin's largest coordinate) by a margin.
const CELL_SLACK: f32 = 1e-5;

/// What a secondary ray leaves: the hit of a primary ray.
#[derive(Clone, Copy, Debug)]
pub enum Origin {
    /// A triangle's vertices and the hit's barycentric weights.
    Triangle {
        /// The triangle's vertices a, b, c, in stored coordinates.
        v: [[f32; 3]; 3],
        /// The hit's weights of a, b and c, summing to one.
        bary: [f32; 3],
    },
    /// A voxel, proxy or R-LOD plane, met by `ray` at `t`, with its unit normal turned towards
    /// the viewer; `scale` is the largest coordinate of the scene's box.
    Cell {
        /// The primary ray that met the cell.
        ray: Ray,
        /// Where along `ray` it met the cell's stand-in.
        t: f32,
        /// How far along the normal what the stand-in stands for may reach from the hit: the
        /// cell's diameter (2r) for a voxel or proxy, the deviation δ for an R-LOD plane.
        clearance: f32,
        /// Unit normal, on the side the primary ray came from.
        normal: [f32; 3],
        /// The largest coordinate of the scene's box: the scale of the positional tolerance.
        scale: f32,
    },
}

impl Origin {
    /// What `hit` of `ray` leaves for secondary rays; `scale` the largest coordinate of the
    /// scene's box. A hit without a usable normal faces back along the ray.
    pub fn of(hit: &Hit, ray: &Ray, scale: f32) -> Origin {
        let back = ray.dir.map(|c| -c);
        let diameter = 2.0 * hit.radius;
        let (normal, clearance) = match &hit.surface {
            Surface::Triangle {
                data,
                triangle,
                bary,
            } => match data.positions.get(*triangle as usize) {
                Some(v) => return Origin::Triangle { v: *v, bary: *bary },
                None => (back, diameter),
            },
            Surface::Proxy(s) => (s.normal(), diameter),
            Surface::Voxel { normal, .. } => (*normal, diameter),
            Surface::Plane {
                normal, deviation, ..
            } => (*normal, *deviation),
        };
        let len = (0..3).map(|k| normal[k] * normal[k]).sum::<f32>().sqrt();
        let usable = len > 0.0 && len.is_finite();
        // Without a normal the ray leaves back along the primary ray, and only the cell's
        // diameter keeps it out of the cell.
        let clearance = if usable { clearance } else { diameter };
        let normal = if usable {
            let n = normal.map(|c| c / len);
            if (0..3).map(|k| n[k] * ray.dir[k]).sum::<f32>() > 0.0 {
                n.map(|c| -c)
            } else {
                n
            }
        } else {
            back
        };
        Origin::Cell {
            ray: *ray,
            t: hit.t,
            clearance,
            normal,
            scale,
        }
    }

    /// The hit point.
    pub fn point(&self) -> [f32; 3] {
        match self {
            Origin::Triangle { v, bary } => triangle_point(v, *bary).0,
            Origin::Cell { ray, t, .. } => [0, 1, 2].map(|k| ray.org[k] + t * ray.dir[k]),
        }
    }

    /// The origin of a ray leaving in direction `dir`.
    pub fn spawn(&self, dir: [f32; 3]) -> [f32; 3] {
        match self {
            Origin::Triangle { v, bary } => from_triangle(v, *bary, dir),
            Origin::Cell {
                ray,
                t,
                clearance,
                normal,
                scale,
            } => from_cell(ray, *t, *clearance, *normal, dir, *scale),
        }
    }
}

/// n·u / (1 − n·u) with u the unit roundoff of f32: the bound of n chained roundings.
pub fn gamma(n: u32) -> f32 {
    let e = f32::EPSILON * 0.5 * n as f32;
    e / (1.0 - e)
}

/// The point Σ bᵢ vᵢ of a triangle and the bound of its rounding error per coordinate.
pub fn triangle_point(v: &[[f32; 3]; 3], bary: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    let mut p = [0.0; 3];
    let mut err = [0.0; 3];
    for k in 0..3 {
        let terms = [bary[0] * v[0][k], bary[1] * v[1][k], bary[2] * v[2][k]];
        p[k] = terms[0] + terms[1] + terms[2];
        err[k] = gamma(7) * (terms[0].abs() + terms[1].abs() + terms[2].abs());
    }
    (p, err)
}

/// The geometric normal (v1 − v0) × (v2 − v0) computed in f64 (so that slivers keep an accurate
/// direction), as a unit vector and its length (twice the area); None without area.
fn normal_and_area(v: &[[f32; 3]; 3]) -> Option<([f64; 3], f64)> {
    let f = |a: [f32; 3]| a.map(f64::from);
    let (a, b, c) = (f(v[0]), f(v[1]), f(v[2]));
    let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    (len > 0.0 && len.is_finite()).then(|| (n.map(|c| c / len), len))
}

/// The unit geometric normal (v1 − v0) × (v2 − v0), computed in f64; None for a triangle
/// without area.
pub fn triangle_normal(v: &[[f32; 3]; 3]) -> Option<[f64; 3]> {
    normal_and_area(v).map(|(n, _)| n)
}

/// The origin of a ray leaving triangle `v` in direction `dir` from the point with weights
/// `bary` (as the kernel returns them).
///
/// The kernel's rounding: it works in coordinates relative to the ray's origin, of size up to
/// M (the distance to the farthest vertex); its edge functions carry errors of some ε·M², and
/// dividing by their sum (twice the projected area, 2A·|cos θ|) gives t an error of some
/// ε·M³ / (A·|cos θ|). A plane at height h lies h / |cos θ| behind the origin along the ray,
/// so h must exceed some ε·M³ / A whatever the direction: thin triangles need more room.
pub fn from_triangle(v: &[[f32; 3]; 3], bary: [f32; 3], dir: [f32; 3]) -> [f32; 3] {
    let (p, err) = triangle_point(v, bary);
    let d64 = dir.map(f64::from);
    let reach = v
        .iter()
        .flat_map(|q| (0..3).map(move |k| f64::from((q[k] - p[k]).abs())))
        .fold(0.0, f64::max)
        * 3f64.sqrt();
    // A triangle without area is never hit by the kernel; should one be given, the ray
    // leaves along its own direction, by the reach.
    let (n, area2) = normal_and_area(v).unwrap_or((d64, 0.0));
    let thin = if area2 > 0.0 {
        reach * reach / area2
    } else {
        1.0
    };
    let along: f64 = (0..3).map(|k| n[k].abs() * f64::from(err[k])).sum();
    let dist = along + f64::from(gamma(KERNEL_GAMMA)) * reach * (1.0 + thin);
    let side = if n[0] * d64[0] + n[1] * d64[1] + n[2] * d64[2] >= 0.0 {
        1.0
    } else {
        -1.0
    };
    let offset = n.map(|c| (c * dist * side) as f32);
    push(p, offset)
}

/// The origin of a ray leaving in direction `dir` a voxel, proxy or plane that `ray` hit at
/// `t`, whose unit normal is `normal` (either side), when what it stands for reaches at most
/// `clearance` from the hit along the normal; `scale` is the largest coordinate of the scene's
/// box, to which the traversal's tolerance is relative. A ray along the surface (no side) moves
/// along itself.
pub fn from_cell(
    ray: &Ray,
    t: f32,
    clearance: f32,
    normal: [f32; 3],
    dir: [f32; 3],
    scale: f32,
) -> [f32; 3] {
    let p = [0, 1, 2].map(|k| ray.org[k] + t * ray.dir[k]);
    let big = |a: [f32; 3]| a.iter().fold(0f32, |m, c| m.max(c.abs()));
    let slack = CELL_SLACK * scale.max(big(ray.org)).max(big(p))
        + gamma(4) * (big(p) + (t * big(ray.dir)).abs() + clearance);
    let dist = clearance + slack;
    let cos: f32 = (0..3).map(|k| normal[k] * dir[k]).sum();
    let len = (0..3).map(|k| dir[k] * dir[k]).sum::<f32>().sqrt();
    let away = if cos > 0.0 {
        normal
    } else if cos < 0.0 {
        normal.map(|c| -c)
    } else {
        dir.map(|c| c / len)
    };
    push(p, away.map(|c| c * dist))
}

/// p + offset, each coordinate rounded one ulp further in the offset's direction.
fn push(p: [f32; 3], offset: [f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|k| {
        let o = p[k] + offset[k];
        if offset[k] > 0.0 {
            next_up(o)
        } else if offset[k] < 0.0 {
            next_down(o)
        } else {
            o
        }
    })
}

/// The smallest f32 above x (x for NaN and +inf).
pub fn next_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f32::from_bits(1);
    }
    let b = x.to_bits();
    f32::from_bits(if x > 0.0 { b + 1 } else { b - 1 })
}

/// The largest f32 below x (x for NaN and −inf).
pub fn next_down(x: f32) -> f32 {
    -next_up(-x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_up_and_down_step_one_ulp_across_zero() {
        assert_eq!(next_up(1.0), 1.0 + f32::EPSILON);
        assert_eq!(next_down(1.0), 1.0 - f32::EPSILON / 2.0);
        assert_eq!(next_up(-0.0), f32::from_bits(1));
        assert_eq!(next_down(0.0), -f32::from_bits(1));
        assert_eq!(next_up(-f32::from_bits(1)), -0.0);
        assert_eq!(next_up(f32::MAX), f32::INFINITY);
        assert!(next_up(f32::NAN).is_nan());
    }

    #[test]
    fn the_origin_leaves_on_the_side_of_the_new_ray() {
        let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let up = from_triangle(&v, [0.5, 0.25, 0.25], [0.3, 0.0, 1.0]);
        let down = from_triangle(&v, [0.5, 0.25, 0.25], [0.3, 0.0, -1.0]);
        assert!(up[2] > 0.0 && down[2] < 0.0);
        assert_eq!(up[..2], [0.25, 0.25]);
        // Far below a pixel: some ulps of the triangle's size.
        assert!(up[2] < 1e-5 && down[2] > -1e-5);
    }

    #[test]
    fn a_cell_hit_starts_beyond_its_clearance_on_the_side_of_the_ray() {
        let ray = Ray::new([0.0, 0.0, -5.0], [0.0, 0.0, 1.0]);
        let n = [0.0, 0.0, -1.0];
        let o = from_cell(&ray, 4.0, 1.0, n, [0.6, 0.0, -0.8], 10.0);
        assert!(o[2] < -2.0 && o[2] > -2.001);
        assert_eq!((o[0], o[1]), (0.0, 0.0));
        let o = from_cell(&ray, 4.0, 1.0, n, [0.6, 0.0, 0.8], 10.0);
        assert!(o[2] > 0.0 && o[2] < 0.001);
    }

    /// A hit at z = −1 of a ray along +z, on a surface whose cell radius is 0.5.
    fn hit_on(surface: Surface) -> (Hit, Ray) {
        let ray = Ray::new([0.0, 0.0, -5.0], [0.0, 0.0, 1.0]);
        let hit = Hit {
            t: 4.0,
            surface,
            radius: 0.5,
            shade: 1.0,
            coverage: 1.0,
            part: None,
        };
        (hit, ray)
    }

    #[test]
    fn a_voxel_clears_its_diameter_and_a_plane_its_deviation() {
        let towards_light = [0.6, 0.0, -0.8];
        let normal = [0.0, 0.0, 1.0];
        let (voxel, ray) = hit_on(Surface::Voxel {
            normal,
            colour: [0.5; 3],
        });
        let o = Origin::of(&voxel, &ray, 10.0).spawn(towards_light);
        assert!(o[2] < -2.0 && o[2] > -2.001, "{o:?}");
        let (plane, ray) = hit_on(Surface::Plane {
            normal,
            colour: [0.5; 3],
            deviation: 0.1,
        });
        let from = Origin::of(&plane, &ray, 10.0);
        assert_eq!(from.point(), [0.0, 0.0, -1.0]);
        let o = from.spawn(towards_light);
        assert!(o[2] < -1.1 && o[2] > -1.101, "{o:?}");
        // A flat plane (δ = 0) moves by the tolerance only.
        let (flat, ray) = hit_on(Surface::Plane {
            normal,
            colour: [0.5; 3],
            deviation: 0.0,
        });
        let o = Origin::of(&flat, &ray, 10.0).spawn(towards_light);
        assert!(o[2] < -1.0 && o[2] > -1.001, "{o:?}");
        // Without a normal the ray backs out of the whole cell.
        let (bad, ray) = hit_on(Surface::Plane {
            normal: [0.0; 3],
            colour: [0.5; 3],
            deviation: 0.1,
        });
        let o = Origin::of(&bad, &ray, 10.0).spawn([0.0, 0.0, -1.0]);
        assert!(o[2] < -2.0 && o[2] > -2.001, "{o:?}");
    }
}
