//! The model-file reader that `demo/build.rs` runs at build time: every kind
//! of malformed or degenerate model is an error naming its line or a face
//! dropped with a warning; the models in `models/` are closed and turned
//! outward. (`fuzz_models.rs` beside it attacks it with proptest.)

#[path = "../build/model_file.rs"]
mod model_file;

use demo::solids::{BEAMS, BEAMS_OUTLINES, LETTER_L, LETTER_L_OUTLINES};
use engine::{Face, Vec3};
use model_file::{parse, ModelError};
use std::collections::HashMap;

const TRIANGLE_VERTICES: &str = "1 0 0 0\n2 10 0 0\n3 0 10 0\n";

fn error_line(text: &str) -> usize {
    match parse(text) {
        Err(ModelError { line, .. }) => line,
        Ok(model) => panic!("accepted: {model:?}"),
    }
}

#[test]
fn malformed_files_are_errors_naming_the_line() {
    let cases = [
        ("1 0 0\nFaces:\n", 1),                               // a coordinate missing
        ("1 0 0 zero\nFaces:\n", 1),                          // not a number
        ("1 0 0 NaN\nFaces:\n", 1),                           // not finite
        ("1 0 0 0\n1 1 1 1\nFaces:\n", 2),                    // a number twice
        ("1 0 0 0\n2 1 0 0\n3 0 1 0\nFaces:\n1 2 3\n", 5),    // no period
        ("1 0 0 0\n2 1 0 0\n3 0 1 0\nFaces:\n1 2.\n", 5),     // two vertices
        ("1 0 0 0\n2 1 0 0\n3 0 1 0\nFaces:\n1 2 4.\n", 5),   // out of range
        ("1 0 0 0\n2 1 0 0\n3 0 1 0\nFaces:\n1 2 3. 7\n", 5), // no such ramp
        ("1 0 0 0\n2 1 0 0\n3 0 1 0\nFaces:\n1 2 3.\nFaces:\n", 6),
        ("1 0 0 0\n", 1), // no faces line
    ];
    for (text, line) in cases {
        assert_eq!(error_line(text), line, "{text:?}");
    }
    // Not flat; crossing itself; through one vertex twice.
    let square = "1 0 0 0\n2 10 0 0\n3 10 10 0\n4 0 10 0\n5 0 10 5\n6 5 5 0\nFaces:\n";
    assert_eq!(error_line(&format!("{square}1 2 3 5.\n")), 8);
    assert_eq!(error_line(&format!("{square}1 3 2 4.\n")), 8);
    assert_eq!(error_line(&format!("{square}1 2 6 3 4 6.\n")), 8);
    // Too many vertices for the engine.
    let many: String = (0..=model_file::MAX_VERTICES)
        .map(|i| format!("{i} {i} 0 0\n"))
        .collect();
    assert_eq!(error_line(&many), model_file::MAX_VERTICES + 1);
}

#[test]
fn faces_without_area_are_dropped_with_a_warning() {
    let text = format!("{TRIANGLE_VERTICES}4 20 0 0\nFaces:\n1 2 3.\n1 2 4.\n1 1 2.\n3 3 3 3.\n");
    let model = parse(&text).unwrap();
    assert_eq!(model.faces.len(), 1);
    let lines: Vec<usize> = model.warnings.iter().map(|w| w.0).collect();
    assert_eq!(lines, [7, 8, 9]);
    // Repeated and collinear corners of a face with area are simply removed.
    let text = format!("{TRIANGLE_VERTICES}4 5 0 0\nFaces:\n1 4 4 2 3 1.\n");
    let model = parse(&text).unwrap();
    assert_eq!(model.faces, [(vec![2, 1, 0], 15)]);
    assert!(model.warnings.is_empty());
}

#[test]
fn the_engine_limits_are_the_readers() {
    assert_eq!(model_file::MAX_VERTICES, engine::MAX_VERTICES);
    assert_eq!(model_file::MAX_FACE_VERTICES, engine::MAX_FACE_VERTICES);
}

/// Every directed edge once, and each reversed once: a closed surface with
/// consistently turned faces; and a positive volume: turned outward (faces
/// are clockwise seen from outside, so the divergence theorem's sum over the
/// counter-clockwise order is the volume).
fn assert_closed_and_outward(faces: &[Face], vertices: &[Vec3], name: &str) {
    let mut edges = HashMap::new();
    let mut volume6 = 0.0;
    for face in faces {
        let v = face.vertices;
        for i in 0..v.len() {
            *edges.entry((v[i], v[(i + 1) % v.len()])).or_insert(0) += 1;
        }
        for i in 1..v.len() - 1 {
            let (a, b, c) = (vertices[v[0]], vertices[v[i + 1]], vertices[v[i]]);
            volume6 += a.dot(b.cross(c));
        }
    }
    for (&(from, to), &count) in &edges {
        assert_eq!(count, 1, "{name}: edge {from}->{to}");
        assert_eq!(
            edges.get(&(to, from)),
            Some(&1),
            "{name}: edge {from}->{to} unmatched"
        );
    }
    assert!(volume6 > 0.0, "{name}: turned inward");
}

#[test]
fn the_letter_l_and_the_beams_are_closed_and_turned_outward() {
    for (model, outlines, name, volume) in [
        (
            &LETTER_L,
            LETTER_L_OUTLINES,
            "letter L",
            30.0 * 40.0 * 10.0 - 20.0 * 30.0 * 10.0,
        ),
        (&BEAMS, BEAMS_OUTLINES, "beams", 0.0),
    ] {
        assert_closed_and_outward(model.faces, model.vertices, name);
        assert_closed_and_outward(outlines, model.vertices, name);
        assert!(model.faces.len() >= outlines.len());
        if volume > 0.0 {
            let mut six = 0.0;
            for face in model.faces {
                let v = face.vertices;
                for i in 1..v.len() - 1 {
                    let (a, b, c) = (
                        model.vertices[v[0]],
                        model.vertices[v[i + 1]],
                        model.vertices[v[i]],
                    );
                    six += a.dot(b.cross(c));
                }
            }
            assert!(
                (six / 6.0 - volume).abs() < 1e-6,
                "{name}: volume {}",
                six / 6.0
            );
        }
    }
    // The L's two L-shaped faces are not convex: cut into triangles.
    assert_eq!(LETTER_L_OUTLINES.len(), 8);
    assert_eq!(LETTER_L.faces.len(), 6 + 2 * 4);
}
