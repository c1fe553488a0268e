//! Models in Ammeraal and Zhang's text format, read when the demo is built
//! (by `demo/build.rs`; the kernel has no file system) and by the tests.
//!
//! The format: one vertex a line, `number x y z`; a line `Faces:`; then one
//! face a line, its vertex numbers counter-clockwise seen from outside, ended
//! by a period. This project adds `#` comments and an optional palette colour
//! (9-15, the colours with shading ramps) after the period.
//!
//! What comes out is ready for the engine: vertices in file order, faces
//! clockwise seen from outside (the engine's convention), and every face that
//! is not convex cut into triangles by ear clipping, since the polygon filler
//! fills convex polygons only. Faces that collapse to nothing are dropped with
//! a warning; everything else that is wrong is an error naming the line.

use std::vec::Vec;
use std::{format, string::String};

/// The engine's fixed limits (`engine::MAX_VERTICES`, `MAX_FACE_VERTICES`).
pub const MAX_VERTICES: usize = 32;
pub const MAX_FACE_VERTICES: usize = 8;
/// Colour of a face that names none.
pub const DEFAULT_COLOUR: u8 = 15;
/// A face's corners may stray this far from its plane (relative to its size):
/// the files hold decimals, so sheared or rotated faces are flat only to
/// their last digit.
const FLATNESS: f64 = 1e-3;

#[derive(Debug, Clone, PartialEq)]
pub struct ParsedModel {
    pub vertices: Vec<[f64; 3]>,
    /// Convex faces (triangles, where the file's face was not convex),
    /// clockwise seen from outside, as indices into `vertices`.
    pub faces: Vec<(Vec<usize>, u8)>,
    /// The file's faces as written (clockwise, repeated corners removed), for
    /// a reference that needs no triangulation.
    pub outlines: Vec<(Vec<usize>, u8)>,
    /// (line, what was dropped and why).
    pub warnings: Vec<(usize, String)>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ModelError {
    /// 1-based line number.
    pub line: usize,
    pub message: String,
}

fn error<T>(line: usize, message: impl Into<String>) -> Result<T, ModelError> {
    Err(ModelError {
        line,
        message: message.into(),
    })
}

pub fn parse(text: &str) -> Result<ParsedModel, ModelError> {
    let mut numbers: Vec<i64> = Vec::new();
    let mut model = ParsedModel {
        vertices: Vec::new(),
        faces: Vec::new(),
        outlines: Vec::new(),
        warnings: Vec::new(),
    };
    let mut in_faces = false;
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let content = raw.split('#').next().unwrap_or("").trim();
        if content.is_empty() {
            continue;
        }
        if content.eq_ignore_ascii_case("faces:") {
            if in_faces {
                return error(line, "a second `Faces:` line");
            }
            in_faces = true;
            continue;
        }
        if !in_faces {
            let (number, point) = parse_vertex(content, line)?;
            if numbers.contains(&number) {
                return error(line, format!("vertex number {number} defined twice"));
            }
            if numbers.len() == MAX_VERTICES {
                return error(line, format!("more than {MAX_VERTICES} vertices"));
            }
            numbers.push(number);
            model.vertices.push(point);
        } else {
            let (refs, colour) = parse_face(content, line)?;
            let mut corners = Vec::new();
            for number in refs {
                match numbers.iter().position(|&n| n == number) {
                    Some(i) => corners.push(i),
                    None => return error(line, format!("face names vertex {number}, not defined")),
                }
            }
            add_face(&mut model, corners, colour, line)?;
        }
    }
    if !in_faces {
        return error(text.lines().count().max(1), "no `Faces:` line");
    }
    if model.faces.is_empty() {
        return error(text.lines().count().max(1), "no faces");
    }
    Ok(model)
}

fn parse_vertex(content: &str, line: usize) -> Result<(i64, [f64; 3]), ModelError> {
    let fields: Vec<&str> = content.split_whitespace().collect();
    if fields.len() != 4 {
        return error(line, "a vertex is `number x y z`");
    }
    let Ok(number) = fields[0].parse::<i64>() else {
        return error(line, format!("`{}` is not a vertex number", fields[0]));
    };
    let mut point = [0.0; 3];
    for (value, field) in point.iter_mut().zip(&fields[1..]) {
        match field.parse::<f64>() {
            Ok(v) if v.is_finite() && v.abs() <= 1e4 => *value = v,
            _ => return error(line, format!("`{field}` is not a coordinate within ±10000")),
        }
    }
    Ok((number, point))
}

fn parse_face(content: &str, line: usize) -> Result<(Vec<i64>, u8), ModelError> {
    let Some((refs, after)) = content.split_once('.') else {
        return error(line, "a face ends with a period");
    };
    let colour = match after.trim() {
        "" => DEFAULT_COLOUR,
        text => match text.parse::<u8>() {
            Ok(c) if (9..=15).contains(&c) => c,
            _ => return error(line, format!("`{text}` is not a colour from 9 to 15")),
        },
    };
    let mut numbers = Vec::new();
    for field in refs.split_whitespace() {
        match field.parse::<i64>() {
            Ok(n) => numbers.push(n),
            Err(_) => return error(line, format!("`{field}` is not a vertex number")),
        }
    }
    if numbers.len() < 3 {
        return error(line, "a face needs at least three vertices");
    }
    Ok((numbers, colour))
}

/// Checks one face, reverses it to the engine's clockwise order, and adds it
/// whole if convex, else as triangles.
fn add_face(
    model: &mut ParsedModel,
    mut corners: Vec<usize>,
    colour: u8,
    line: usize,
) -> Result<(), ModelError> {
    // The same vertex twice in a row is no edge: drop the repeat.
    corners.dedup();
    while corners.len() > 1 && corners.first() == corners.last() {
        corners.pop();
    }
    let points: Vec<[f64; 3]> = corners.iter().map(|&i| model.vertices[i]).collect();
    // Collinear corners add nothing either.
    let keep: Vec<usize> = (0..corners.len())
        .filter(|&i| {
            let n = corners.len();
            let (a, b, c) = (points[(i + n - 1) % n], points[i], points[(i + 1) % n]);
            length(cross(sub(b, a), sub(c, b))) > 1e-9 * (length(sub(b, a)) + length(sub(c, b)))
        })
        .collect();
    let corners: Vec<usize> = keep.iter().map(|&i| corners[i]).collect();
    let points: Vec<[f64; 3]> = keep.iter().map(|&i| points[i]).collect();
    if corners.len() < 3 {
        model
            .warnings
            .push((line, String::from("face dropped: it has no area")));
        return Ok(());
    }
    let mut sorted = corners.clone();
    sorted.sort_unstable();
    if sorted.windows(2).any(|w| w[0] == w[1]) {
        return error(line, "a face passes through one vertex twice");
    }
    let normal = newell(&points);
    let size = points
        .iter()
        .map(|p| length(sub(*p, points[0])))
        .fold(0.0, f64::max);
    if length(normal) <= 1e-9 * size * size {
        model
            .warnings
            .push((line, String::from("face dropped: it has no area")));
        return Ok(());
    }
    let unit = scale(normal, 1.0 / length(normal));
    if points
        .iter()
        .any(|p| dot(sub(*p, points[0]), unit).abs() > FLATNESS * size)
    {
        return error(line, "a face is not flat");
    }
    // The file runs counter-clockwise seen from outside; the engine wants
    // clockwise.
    let clockwise: Vec<usize> = corners.iter().rev().copied().collect();
    model.outlines.push((clockwise.clone(), colour));
    let flat = flatten(&clockwise, &model.vertices, unit);
    if is_convex(&flat) && clockwise.len() <= MAX_FACE_VERTICES {
        model.faces.push((clockwise, colour));
        return Ok(());
    }
    match ear_clip(&flat) {
        Some(triangles) => {
            for [a, b, c] in triangles {
                model
                    .faces
                    .push((vec![clockwise[a], clockwise[b], clockwise[c]], colour));
            }
            Ok(())
        }
        None => error(line, "a face crosses itself"),
    }
}

/// The face in its own plane, as 2-D points (the ear clipper and the
/// convexity test need only the signs of turns relative to the polygon's own
/// orientation, so which way the frame faces does not matter).
fn flatten(corners: &[usize], vertices: &[[f64; 3]], normal: [f64; 3]) -> Vec<[f64; 2]> {
    let helper = if normal[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let u = cross(helper, normal);
    let u = scale(u, 1.0 / length(u));
    let v = cross(normal, u);
    corners
        .iter()
        .map(|&i| [dot(vertices[i], u), dot(vertices[i], v)])
        .collect()
}

/// Twice the signed area: its sign is the polygon's orientation in the frame.
fn area2(p: &[[f64; 2]]) -> f64 {
    (0..p.len())
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum()
}

fn turn(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
}

fn is_convex(p: &[[f64; 2]]) -> bool {
    let n = p.len();
    let sign = area2(p).signum();
    (0..n).all(|i| turn(p[i], p[(i + 1) % n], p[(i + 2) % n]) * sign > 0.0)
}

/// Ear clipping: repeatedly cut off a corner whose triangle turns the way the
/// polygon does and holds no other corner. `None` if no ear can be found
/// (the polygon crosses itself).
fn ear_clip(p: &[[f64; 2]]) -> Option<Vec<[usize; 3]>> {
    let sign = area2(p).signum();
    let mut left: Vec<usize> = (0..p.len()).collect();
    let mut triangles = Vec::new();
    while left.len() > 3 {
        let n = left.len();
        let ear = (0..n).find(|&i| {
            let (a, b, c) = (left[(i + n - 1) % n], left[i], left[(i + 1) % n]);
            turn(p[a], p[b], p[c]) * sign > 0.0
                && left
                    .iter()
                    .filter(|&&k| k != a && k != b && k != c)
                    .all(|&k| !inside_or_on(p[k], p[a], p[b], p[c], sign))
        })?;
        let (a, b, c) = (left[(ear + n - 1) % n], left[ear], left[(ear + 1) % n]);
        triangles.push([a, b, c]);
        left.remove(ear);
    }
    if turn(p[left[0]], p[left[1]], p[left[2]]) * sign <= 0.0 {
        return None;
    }
    triangles.push([left[0], left[1], left[2]]);
    Some(triangles)
}

fn inside_or_on(q: [f64; 2], a: [f64; 2], b: [f64; 2], c: [f64; 2], sign: f64) -> bool {
    [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(s, e)| turn(s, e, q) * sign >= 0.0)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn scale(a: [f64; 3], k: f64) -> [f64; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

fn length(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Newell's normal of the corners in their order (the file's
/// counter-clockwise order gives the outward normal).
fn newell(points: &[[f64; 3]]) -> [f64; 3] {
    let mut n = [0.0; 3];
    for i in 0..points.len() {
        let (p, q) = (points[i], points[(i + 1) % points.len()]);
        n[0] += (p[1] - q[1]) * (p[2] + q[2]);
        n[1] += (p[2] - q[2]) * (p[0] + q[0]);
        n[2] += (p[0] - q[0]) * (p[1] + q[1]);
    }
    n
}
