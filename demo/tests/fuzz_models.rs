//! The model-file reader that `demo/build.rs` runs at build time, under
//! attack: any text is read without a panic, and whatever model it accepts —
//! repeated and collinear corners, faces without area, any pose — the engine
//! takes and draws without a panic and without a write outside the page.
//!
//! The case count is PROPTEST_CASES, as in `fuzz_raster.rs`.

#[path = "../build/model_file.rs"]
mod model_file;

#[path = "common/fuzzing.rs"]
mod fuzzing;

use demo::frame::{render_faces_with_depth, BACKGROUND};
use engine::{DepthBuffer, Face, Model, Object, Vec3, Xform};
use model_file::parse;
use modex::soft::SoftVga;
use modex::{ModeX, Page, PageSpans, PAGE_BYTES, PAGE_PIXELS};
use proptest::prelude::*;

const DEFAULT_CASES: u32 = 1000;

fn config() -> ProptestConfig {
    fuzzing::proptest_config(DEFAULT_CASES)
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
    #![proptest_config(config())]

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
        let mut depths = Box::new(DepthBuffer::new());
        render_faces_with_depth(&mut image, &mut PageSpans::all(), &mut depths, |draw| {
            object.each_visible_face(|visible| draw(visible, visible.face.colour))
        });
        // Through the page update onto the software VGA, which flags any
        // write outside the page being drawn.
        let mut soft = Box::new(SoftVga::new());
        ModeX::new(&mut *soft).set_mode();
        let page = Page::One;
        soft.set_write_guard(Some(page.base()..page.base() + PAGE_BYTES));
        let mut shadow = Box::new([BACKGROUND; PAGE_PIXELS]);
        ModeX::new(&mut *soft).update_page(page, &mut shadow, &image, &PageSpans::all());
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
