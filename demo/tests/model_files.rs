//! The model-file reader that `demo/build.rs` runs at build time, under
//! attack: every kind of malformed or degenerate model is an error naming its
//! line or a face dropped with a warning, never a panic; and whatever it
//! accepts draws without a panic and without a write outside the page.
//! Also: the models in `models/` are closed and turned outward.

#[path = "../build/model_file.rs"]
mod model_file;

use demo::frame::{render_faces_with_depth, BACKGROUND};
use demo::solids::{BEAMS, BEAMS_OUTLINES, LETTER_L, LETTER_L_OUTLINES};
use engine::{DepthBand, Face, Model, Object, Vec3, Xform};
use model_file::{parse, ModelError};
use modex::soft::SoftVga;
use modex::{ModeX, Page, PAGE_BYTES, PAGE_PIXELS};
use proptest::prelude::*;
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

fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        (-40i32..40).prop_map(f64::from), // repeats and collinear points likely
        -50.0f64..50.0,
        Just(0.0),
    ]
}

/// A file of `count` vertices (numbers 1..) and faces of any length that
/// mostly name them and now and then a number out of range.
fn model_text() -> impl Strategy<Value = String> {
    (1usize..12)
        .prop_flat_map(|count| {
            let reference = prop_oneof![60 => 1..=count as i64, 1 => 0..count as i64 + 3];
            let vertices = prop::collection::vec((coordinate(), coordinate(), coordinate()), count);
            let face = (
                prop_oneof![
                    // Triangles are always flat; longer faces rarely are.
                    6 => prop::collection::vec(reference.clone(), 3..4),
                    1 => prop::collection::vec(reference, 2..9),
                ],
                prop::option::of(prop_oneof![20 => 9u8..=15, 1 => 5u8..17]),
            );
            (vertices, prop::collection::vec(face, 1..8))
        })
        .prop_map(|(vertices, faces)| {
            let mut text = String::new();
            for (i, (x, y, z)) in vertices.iter().enumerate() {
                text += &format!("{} {x} {y} {z}\n", i + 1);
            }
            text += "Faces:\n";
            for (refs, colour) in faces {
                let refs: Vec<String> = refs.iter().map(|r| r.to_string()).collect();
                let colour = colour.map(|c| format!(" {c}")).unwrap_or_default();
                text += &format!("{}.{colour}\n", refs.join(" "));
            }
            text
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn any_text_is_read_without_a_panic(text in "[0-9 .#:a-zA-Z\\-\n]{0,200}") {
        let _ = parse(&text);
    }

    /// Whatever the reader accepts, the engine takes, and it draws inside the
    /// page whatever its pose.
    #[test]
    fn accepted_models_draw_without_a_panic_or_a_stray_write(
        text in model_text(),
        position in (-60.0f64..60.0, -60.0f64..60.0, -300.0f64..10.0),
        turn in (0.0f64..6.3, 0.0f64..6.3),
    ) {
        let Ok(parsed) = parse(&text) else { return Ok(()) };
        for (corners, colour) in &parsed.faces {
            prop_assert!(corners.len() >= 3 && corners.len() <= model_file::MAX_FACE_VERTICES);
            prop_assert!(corners.iter().all(|&c| c < parsed.vertices.len()));
            prop_assert!((9..=15).contains(colour));
        }
        let vertices: Vec<Vec3> = parsed.vertices.iter().map(|&[x, y, z]| Vec3::new(x, y, z)).collect();
        let faces: Vec<Face> = parsed
            .faces
            .iter()
            .map(|(corners, colour)| Face::new(Vec::leak(corners.clone()), *colour))
            .collect();
        let model: &'static Model = Box::leak(Box::new(Model {
            vertices: Vec::leak(vertices),
            faces: Vec::leak(faces),
        }));
        let mut xform = Xform::translation(position.0, position.1, position.2);
        xform.append_rotation_x(turn.0);
        xform.append_rotation_y(turn.1);
        let mut object = Object::new(model, xform);
        let mut image = Box::new([BACKGROUND; PAGE_PIXELS]);
        let mut band = Box::new(DepthBand::new());
        render_faces_with_depth(&mut image, &mut band, |draw| {
            object.each_visible_face(|visible| draw(visible, visible.face.colour))
        });
        // Through the page update onto the software VGA, which flags any
        // write outside the page being drawn.
        let mut soft = Box::new(SoftVga::new());
        ModeX::new(&mut *soft).set_mode();
        let page = Page(1);
        soft.set_write_guard(Some(page.base()..page.base() + PAGE_BYTES));
        let mut shadow = Box::new([BACKGROUND; PAGE_PIXELS]);
        ModeX::new(&mut *soft).update_page(page, &mut shadow, &image);
        prop_assert_eq!(soft.guard_violations(), 0);
        prop_assert!(shadow == image);
    }
}

#[test]
fn the_generated_models_are_often_accepted() {
    // Else the drawing property above would test almost nothing.
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let strategy = model_text();
    let accepted = (0..500)
        .filter(|_| parse(&strategy.new_tree(&mut runner).unwrap().current()).is_ok())
        .count();
    assert!(accepted > 50, "{accepted} of 500 accepted");
}
