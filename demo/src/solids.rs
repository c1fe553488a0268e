//! The convex solids the demo can show: Abrash's cube and four more
//! Platonic solids of about the same size (every vertex about 26 units from
//! the centre). Faces run clockwise seen from outside, so backface removal
//! alone hides exactly the faces turned away; the tests check that for every
//! face of every solid, and that neighbouring faces differ in colour.

use engine::{Face, Model, Vec3};

/// The golden ratio, which places the icosahedron's and dodecahedron's
/// vertices.
const PHI: f64 = core::f64::consts::GOLDEN_RATIO;

/// Abrash's cube: eight shared vertices in his listing's order (vertex 6 is
/// (-15, -15, 15); the OCR of the listing lost a digit there), six faces in
/// Abrash's colours (white, yellow, bright red, bright cyan, bright green,
/// bright blue).
pub static CUBE: Model = Model {
    vertices: &[
        Vec3::new(15.0, 15.0, 15.0),
        Vec3::new(15.0, 15.0, -15.0),
        Vec3::new(15.0, -15.0, 15.0),
        Vec3::new(15.0, -15.0, -15.0),
        Vec3::new(-15.0, 15.0, 15.0),
        Vec3::new(-15.0, 15.0, -15.0),
        Vec3::new(-15.0, -15.0, 15.0),
        Vec3::new(-15.0, -15.0, -15.0),
    ],
    faces: &[
        Face::new(&[1, 3, 2, 0], 15),
        Face::new(&[5, 7, 3, 1], 14),
        Face::new(&[4, 5, 1, 0], 12),
        Face::new(&[3, 7, 6, 2], 11),
        Face::new(&[5, 4, 6, 7], 10),
        Face::new(&[0, 2, 6, 4], 9),
    ],
};

/// Half the edge of the cube whose alternate corners make the tetrahedron.
const S: f64 = 15.0;

/// Four triangles.
pub static TETRAHEDRON: Model = Model {
    vertices: &[
        Vec3::new(S, S, S),
        Vec3::new(S, -S, -S),
        Vec3::new(-S, S, -S),
        Vec3::new(-S, -S, S),
    ],
    faces: &[
        Face::new(&[2, 1, 0], 15),
        Face::new(&[1, 3, 0], 14),
        Face::new(&[3, 2, 0], 12),
        Face::new(&[2, 3, 1], 11),
    ],
};

/// The octahedron's vertices lie on the axes, this far out.
const R: f64 = 26.0;

/// Eight triangles.
pub static OCTAHEDRON: Model = Model {
    vertices: &[
        Vec3::new(R, 0.0, 0.0),
        Vec3::new(-R, 0.0, 0.0),
        Vec3::new(0.0, R, 0.0),
        Vec3::new(0.0, -R, 0.0),
        Vec3::new(0.0, 0.0, R),
        Vec3::new(0.0, 0.0, -R),
    ],
    faces: &[
        Face::new(&[4, 2, 0], 15),
        Face::new(&[2, 5, 0], 14),
        Face::new(&[3, 4, 0], 12),
        Face::new(&[5, 3, 0], 11),
        Face::new(&[2, 4, 1], 10),
        Face::new(&[5, 2, 1], 9),
        Face::new(&[4, 3, 1], 15),
        Face::new(&[3, 5, 1], 14),
    ],
};

/// The icosahedron's vertices are the corners of three golden rectangles,
/// A by A·φ, in the three coordinate planes.
const A: f64 = 13.5;

/// Twenty triangles.
pub static ICOSAHEDRON: Model = Model {
    vertices: &[
        Vec3::new(0.0, A, A * PHI),
        Vec3::new(A * PHI, 0.0, A),
        Vec3::new(A, A * PHI, 0.0),
        Vec3::new(0.0, A, -A * PHI),
        Vec3::new(-A * PHI, 0.0, A),
        Vec3::new(A, -A * PHI, 0.0),
        Vec3::new(0.0, -A, A * PHI),
        Vec3::new(A * PHI, 0.0, -A),
        Vec3::new(-A, A * PHI, 0.0),
        Vec3::new(0.0, -A, -A * PHI),
        Vec3::new(-A * PHI, 0.0, -A),
        Vec3::new(-A, -A * PHI, 0.0),
    ],
    faces: &[
        Face::new(&[2, 1, 0], 15),
        Face::new(&[1, 6, 0], 14),
        Face::new(&[8, 2, 0], 12),
        Face::new(&[6, 4, 0], 11),
        Face::new(&[4, 8, 0], 10),
        Face::new(&[2, 7, 1], 9),
        Face::new(&[5, 6, 1], 15),
        Face::new(&[7, 5, 1], 14),
        Face::new(&[3, 7, 2], 12),
        Face::new(&[8, 3, 2], 11),
        Face::new(&[9, 7, 3], 10),
        Face::new(&[8, 10, 3], 9),
        Face::new(&[10, 9, 3], 15),
        Face::new(&[6, 11, 4], 14),
        Face::new(&[10, 8, 4], 12),
        Face::new(&[11, 10, 4], 11),
        Face::new(&[11, 6, 5], 10),
        Face::new(&[7, 9, 5], 9),
        Face::new(&[9, 11, 5], 15),
        Face::new(&[10, 11, 9], 14),
    ],
};

/// The dodecahedron holds Abrash's cube (corners ±B) and twelve more
/// vertices on three golden rectangles, B/φ by B·φ.
const B: f64 = 15.0;

/// Twelve pentagons.
pub static DODECAHEDRON: Model = Model {
    vertices: &[
        Vec3::new(B, B, B),
        Vec3::new(B, B, -B),
        Vec3::new(B, -B, B),
        Vec3::new(B, -B, -B),
        Vec3::new(-B, B, B),
        Vec3::new(-B, B, -B),
        Vec3::new(-B, -B, B),
        Vec3::new(-B, -B, -B),
        Vec3::new(0.0, B / PHI, B * PHI),
        Vec3::new(B * PHI, 0.0, B / PHI),
        Vec3::new(B / PHI, B * PHI, 0.0),
        Vec3::new(0.0, B / PHI, -B * PHI),
        Vec3::new(-B * PHI, 0.0, B / PHI),
        Vec3::new(B / PHI, -B * PHI, 0.0),
        Vec3::new(0.0, -B / PHI, B * PHI),
        Vec3::new(B * PHI, 0.0, -B / PHI),
        Vec3::new(-B / PHI, B * PHI, 0.0),
        Vec3::new(0.0, -B / PHI, -B * PHI),
        Vec3::new(-B * PHI, 0.0, -B / PHI),
        Vec3::new(-B / PHI, -B * PHI, 0.0),
    ],
    faces: &[
        Face::new(&[1, 15, 9, 0, 10], 15),
        Face::new(&[2, 14, 8, 0, 9], 14),
        Face::new(&[4, 16, 10, 0, 8], 12),
        Face::new(&[17, 3, 15, 1, 11], 11),
        Face::new(&[16, 5, 11, 1, 10], 10),
        Face::new(&[15, 3, 13, 2, 9], 9),
        Face::new(&[19, 6, 14, 2, 13], 15),
        Face::new(&[7, 19, 13, 3, 17], 14),
        Face::new(&[18, 5, 16, 4, 12], 11),
        Face::new(&[14, 6, 12, 4, 8], 10),
        Face::new(&[7, 17, 11, 5, 18], 12),
        Face::new(&[7, 18, 12, 6, 19], 9),
    ],
};

/// A solid with the name the on-screen display gives it.
#[derive(Debug)]
pub struct Solid {
    /// As the statistics line shows it.
    pub name: &'static str,
    /// Vertices and faces.
    pub model: &'static Model,
    /// Convex, so that backface removal alone hides exactly what it must
    /// when it is the only object (the renderer then needs no depth test).
    pub convex: bool,
}

/// The convex solids, the starting cube first.
const PLATONIC: [Solid; 5] = [
    Solid {
        name: "cube",
        model: &CUBE,
        convex: true,
    },
    Solid {
        name: "tetrahedron",
        model: &TETRAHEDRON,
        convex: true,
    },
    Solid {
        name: "octahedron",
        model: &OCTAHEDRON,
        convex: true,
    },
    Solid {
        name: "dodecahedron",
        model: &DODECAHEDRON,
        convex: true,
    },
    Solid {
        name: "icosahedron",
        model: &ICOSAHEDRON,
        convex: true,
    },
];

/// The convex solids, the starting cube first.
pub static SOLIDS: [Solid; 5] = PLATONIC;

/// The models read from `models/` when the demo was built (see
/// `demo/build.rs`): Ammeraal and Zhang's solid letter L and their three
/// beams, neither convex, so only the depth test hides them right.
mod from_files {
    use engine::{Face, Model, Vec3};
    include!(concat!(env!("OUT_DIR"), "/models.rs"));
}
pub use from_files::{BEAMS, BEAMS_OUTLINES, LETTER_L, LETTER_L_OUTLINES};

/// The order N steps through: the Platonic solids, then the models from files.
pub static SHAPES: [Solid; 7] = {
    let [cube, tetrahedron, octahedron, dodecahedron, icosahedron] = PLATONIC;
    [
        cube,
        tetrahedron,
        octahedron,
        dodecahedron,
        icosahedron,
        Solid {
            name: "letter L",
            model: &LETTER_L,
            convex: false,
        },
        Solid {
            name: "three beams",
            model: &BEAMS,
            convex: false,
        },
    ]
};

#[cfg(test)]
mod tests {
    use super::*;
    use engine::{outward_normal, MAX_FACE_VERTICES, MAX_VERTICES};
    use std::collections::HashMap;
    use std::vec::Vec;

    fn corners(model: &Model, face: &Face) -> Vec<Vec3> {
        face.vertices.iter().map(|&v| model.vertices[v]).collect()
    }

    fn centroid(points: &[Vec3]) -> Vec3 {
        points.iter().fold(Vec3::default(), |sum, &p| sum + p) * (1.0 / points.len() as f64)
    }

    #[test]
    fn every_face_of_every_solid_is_clockwise_seen_from_outside() {
        for solid in &SOLIDS {
            let model = solid.model;
            let centre = centroid(model.vertices);
            for (index, face) in model.faces.iter().enumerate() {
                let points = corners(model, face);
                let outward = centroid(&points) - centre;
                // At every corner, clockwise seen from outside (right-handed,
                // y up) means (previous − here) × (next − here) points out.
                let count = points.len();
                for corner in 0..count {
                    let here = points[corner];
                    let previous = points[(corner + count - 1) % count];
                    let next = points[(corner + 1) % count];
                    let turn = (previous - here).cross(next - here);
                    assert!(
                        turn.dot(outward) > 1e-6,
                        "{} face {index} turns the wrong way at corner {corner}",
                        solid.name
                    );
                }
                // The shading normal agrees.
                let normal = outward_normal(points.iter().copied());
                assert!(
                    normal.dot(outward) > 0.0,
                    "{} face {index}: normal points in",
                    solid.name
                );
            }
        }
    }

    #[test]
    fn every_face_is_flat_and_the_solid_is_convex() {
        for solid in &SOLIDS {
            let model = solid.model;
            for (index, face) in model.faces.iter().enumerate() {
                let points = corners(model, face);
                let normal = outward_normal(points.iter().copied());
                let plane = normal.dot(points[0]);
                for point in &points {
                    assert!(
                        (normal.dot(*point) - plane).abs() < 1e-9,
                        "{} face {index} is not flat",
                        solid.name
                    );
                }
                // Convex: every vertex of the solid is on or behind each face.
                for vertex in model.vertices {
                    assert!(
                        normal.dot(*vertex) <= plane + 1e-9,
                        "{} is not convex at face {index}",
                        solid.name
                    );
                }
            }
        }
    }

    #[test]
    fn every_solid_is_closed_and_each_edge_is_walked_once_each_way() {
        for solid in &SOLIDS {
            let model = solid.model;
            let mut edges = HashMap::new();
            for face in model.faces {
                let count = face.vertices.len();
                for corner in 0..count {
                    let edge = (face.vertices[corner], face.vertices[(corner + 1) % count]);
                    *edges.entry(edge).or_insert(0) += 1;
                }
            }
            for (&(from, to), &uses) in &edges {
                assert_eq!(uses, 1, "{}: edge {from}->{to} walked twice", solid.name);
                assert_eq!(
                    edges.get(&(to, from)),
                    Some(&1),
                    "{}: edge {from}->{to} has no opposite",
                    solid.name
                );
            }
            // Euler: V − E + F = 2 for a closed convex solid.
            let (v, e, f) = (model.vertices.len(), edges.len() / 2, model.faces.len());
            assert_eq!(v + f, e + 2, "{}", solid.name);
            assert!(v <= MAX_VERTICES);
            assert!(model
                .faces
                .iter()
                .all(|f| f.vertices.len() <= MAX_FACE_VERTICES));
        }
    }

    #[test]
    fn every_vertex_is_on_a_sphere_about_the_size_of_abrashs_cube() {
        let cube_radius = CUBE.vertices[0].length();
        for solid in &SOLIDS {
            for vertex in solid.model.vertices {
                let radius = vertex.length();
                let radius_of_first = solid.model.vertices[0].length();
                assert!((radius - radius_of_first).abs() < 1e-9, "{}", solid.name);
                assert!(
                    (radius / cube_radius - 1.0).abs() < 0.02,
                    "{}: radius {radius}",
                    solid.name
                );
            }
        }
    }

    #[test]
    fn neighbouring_faces_differ_in_colour() {
        for solid in &SOLIDS {
            let faces = solid.model.faces;
            let mut edge_owner = HashMap::new();
            for (index, face) in faces.iter().enumerate() {
                let count = face.vertices.len();
                for corner in 0..count {
                    let edge = (face.vertices[corner], face.vertices[(corner + 1) % count]);
                    edge_owner.insert(edge, index);
                }
            }
            for (&(from, to), &owner) in &edge_owner {
                let neighbour = edge_owner[&(to, from)];
                assert_ne!(
                    faces[owner].colour, faces[neighbour].colour,
                    "{}: faces {owner} and {neighbour}",
                    solid.name
                );
            }
        }
    }
}
