//! An independent reference for hidden surfaces: for each pixel centre, a ray
//! from the eye is intersected with every face of every object (no culling,
//! no scan conversion, no depth buffer, no triangles: the faces as the model
//! files write them), and the nearest hit gives the pixel its colour.
//!
//! It shares no code with the renderer: its own projection (exact, not
//! rounded to whole pixels), its own plane intersection in `f64` and an
//! even-odd point-in-polygon test that is right for non-convex faces.

use demo::solids::{BEAMS, BEAMS_OUTLINES, LETTER_L, LETTER_L_OUTLINES};
use engine::{Face, Object, Vec3, NEAREST_DRAWN_Z};

pub const WIDTH: usize = 320;
pub const HEIGHT: usize = 240;
/// The projection the renderer uses: screen X = 160 + K·x/z, Y = 120 − K·y/z.
const K: f64 = -320.0;

/// What the reference sees at each pixel: the colour, and which face of which
/// object (0 for the background), to tell where edges are.
pub struct Picture {
    pub colour: Vec<u8>,
    pub id: Vec<u32>,
    /// Pixels whose centre lies within a pixel of an edge of a face that
    /// faces the viewer, hidden or not: the renderer rounds each vertex to
    /// the nearest pixel, so a face may cover a pixel more or less there, and
    /// where it covers one more its plane, extended past the face, may
    /// wrongly come out nearest.
    pub near_an_edge: Vec<bool>,
}

/// A face's corners in view space and its colour.
struct Polygon {
    corners: Vec<Vec3>,
    colour: u8,
    id: u32,
}

/// The faces as written in the model file for models read from files, the
/// model's own faces (already convex) for the others.
fn outlines(object: &Object) -> &'static [Face] {
    let model = object.model();
    if core::ptr::eq(model, &LETTER_L) {
        LETTER_L_OUTLINES
    } else if core::ptr::eq(model, &BEAMS) {
        BEAMS_OUTLINES
    } else {
        model.faces
    }
}

/// Casts a ray through every pixel centre. Objects reaching nearer than
/// `NEAREST_DRAWN_Z` are left out, as the renderer leaves them out.
pub fn cast(objects: &[Object], background: u8) -> Picture {
    let mut picture = Picture {
        colour: vec![background; WIDTH * HEIGHT],
        id: vec![0; WIDTH * HEIGHT],
        near_an_edge: vec![false; WIDTH * HEIGHT],
    };
    let mut nearest = vec![f64::NEG_INFINITY; WIDTH * HEIGHT];
    for (object_index, object) in objects.iter().enumerate() {
        let count = object.model().vertices.len();
        let view: Vec<Vec3> = (0..count).map(|i| object.view_vertex(i)).collect();
        if !view.iter().all(|v| v.z <= NEAREST_DRAWN_Z) {
            continue;
        }
        for (face_index, face) in outlines(object).iter().enumerate() {
            let polygon = Polygon {
                corners: face.vertices.iter().map(|&v| view[v]).collect(),
                colour: face.colour,
                id: (object_index as u32 + 1) * 1000 + face_index as u32,
            };
            cast_face(&polygon, &mut picture, &mut nearest);
        }
    }
    picture
}

fn cast_face(polygon: &Polygon, picture: &mut Picture, nearest: &mut [f64]) {
    let c = &polygon.corners;
    // Newell's normal; any point of the face is on its plane.
    let mut normal = Vec3::default();
    for i in 0..c.len() {
        let (p, q) = (c[i], c[(i + 1) % c.len()]);
        normal = normal
            + Vec3::new(
                (p.y - q.y) * (p.z + q.z),
                (p.z - q.z) * (p.x + q.x),
                (p.x - q.x) * (p.y + q.y),
            );
    }
    let d = normal.dot(c[0]);
    // Only pixels inside the face's exact screen bounding box can hit it.
    let screen: Vec<(f64, f64)> = c
        .iter()
        .map(|p| (160.0 + K * p.x / p.z, 120.0 - K * p.y / p.z))
        .collect();
    let x0 = screen
        .iter()
        .map(|s| s.0)
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(0.0) as usize;
    let x1 = screen
        .iter()
        .map(|s| s.0)
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .min(WIDTH as f64 - 1.0);
    let y0 = screen
        .iter()
        .map(|s| s.1)
        .fold(f64::INFINITY, f64::min)
        .floor()
        .max(0.0) as usize;
    let y1 = screen
        .iter()
        .map(|s| s.1)
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        .min(HEIGHT as f64 - 1.0);
    if x1 < 0.0 || y1 < 0.0 {
        return;
    }
    // Clockwise on the screen (y down) is facing the viewer.
    let twice_area: f64 = (0..screen.len())
        .map(|i| {
            let (a, b) = (screen[i], screen[(i + 1) % screen.len()]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum();
    if twice_area > 0.0 {
        for i in 0..screen.len() {
            mark_band(
                screen[i],
                screen[(i + 1) % screen.len()],
                &mut picture.near_an_edge,
            );
        }
    }
    // Drop the normal's largest axis to test containment in 2-D.
    let axis = if normal.x.abs() >= normal.y.abs() && normal.x.abs() >= normal.z.abs() {
        0
    } else if normal.y.abs() >= normal.z.abs() {
        1
    } else {
        2
    };
    let flat = |p: Vec3| match axis {
        0 => (p.y, p.z),
        1 => (p.z, p.x),
        _ => (p.x, p.y),
    };
    let corners2: Vec<(f64, f64)> = c.iter().map(|&p| flat(p)).collect();
    for y in y0..=y1 as usize {
        for x in x0..=x1 as usize {
            // The ray through the pixel centre: points s·(u, v, 1), s < 0.
            let ray = Vec3::new((x as f64 - 160.0) / K, -(y as f64 - 120.0) / K, 1.0);
            let along = normal.dot(ray);
            if along == 0.0 {
                continue;
            }
            let s = d / along;
            if s >= 0.0 {
                continue; // behind the eye
            }
            let i = y * WIDTH + x;
            if s <= nearest[i] {
                continue; // z = s: nearer means larger
            }
            if contains(&corners2, flat(ray * s)) {
                nearest[i] = s;
                picture.colour[i] = polygon.colour;
                picture.id[i] = polygon.id;
            }
        }
    }
}

/// Marks the pixels whose centre is within one pixel of the segment a–b.
fn mark_band(a: (f64, f64), b: (f64, f64), band: &mut [bool]) {
    let clamp_x = |v: f64| v.clamp(-1.0, WIDTH as f64) as i64;
    let clamp_y = |v: f64| v.clamp(-1.0, HEIGHT as f64) as i64;
    let (x0, x1) = (
        clamp_x(a.0.min(b.0).floor() - 1.0),
        clamp_x(a.0.max(b.0).ceil() + 1.0),
    );
    let (y0, y1) = (
        clamp_y(a.1.min(b.1).floor() - 1.0),
        clamp_y(a.1.max(b.1).ceil() + 1.0),
    );
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let length2 = dx * dx + dy * dy;
    for y in y0.max(0)..=y1.min(HEIGHT as i64 - 1) {
        for x in x0.max(0)..=x1.min(WIDTH as i64 - 1) {
            let (px, py) = (x as f64 - a.0, y as f64 - a.1);
            let t = if length2 > 0.0 {
                ((px * dx + py * dy) / length2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (ex, ey) = (px - t * dx, py - t * dy);
            if ex * ex + ey * ey <= 1.0 {
                band[y as usize * WIDTH + x as usize] = true;
            }
        }
    }
}

/// Even-odd rule: a ray from `q` toward +x crosses the outline an odd number
/// of times.
fn contains(polygon: &[(f64, f64)], q: (f64, f64)) -> bool {
    let mut inside = false;
    for i in 0..polygon.len() {
        let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
        if (a.1 > q.1) != (b.1 > q.1) {
            let x = a.0 + (q.1 - a.1) / (b.1 - a.1) * (b.0 - a.0);
            if q.0 < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// Pixels where `frame` differs from the reference, leaving out the one-pixel
/// band along edges: along the edges of faces that face the viewer (see
/// `Picture::near_an_edge`), and where a neighbouring pixel shows another face
/// or the background in the reference (which also takes in the lines where
/// interpenetrating faces cross).
pub fn differences_off_the_edges(frame: &[u8], reference: &Picture) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let i = y * WIDTH + x;
            if frame[i] == reference.colour[i] || reference.near_an_edge[i] {
                continue;
            }
            let on_an_edge = (y.saturating_sub(1)..=(y + 1).min(HEIGHT - 1)).any(|ny| {
                (x.saturating_sub(1)..=(x + 1).min(WIDTH - 1))
                    .any(|nx| reference.id[ny * WIDTH + nx] != reference.id[i])
            });
            if !on_an_edge {
                out.push((x, y));
            }
        }
    }
    out
}
