//! The depth-buffered frame against an independent ray caster
//! (`common/ray_caster.rs`): the three beams, the letter L, interpenetrating
//! solids, the cube inside the octahedron's orbit and 1,000 random poses of
//! the three-object scene must equal it everywhere but a one-pixel band along
//! edges; and the painter's order must not, on the beams.

#[path = "common/ray_caster.rs"]
mod ray_caster;

use demo::frame::{render_painter, render_to_image, BACKGROUND};
use demo::scene::{Axis, Scene, SceneCommand, Sense};
use engine::{fill_convex_polygon, Xform};
use modex::PAGE_PIXELS;
use ray_caster::{cast, differences_off_the_edges, WIDTH};

fn frame(scene: &mut Scene) -> Vec<u8> {
    let mut image = Box::new([0u8; PAGE_PIXELS]);
    render_to_image(scene, &mut image);
    image.to_vec()
}

/// Asserts the frame equals the reference off the edges, and that the scene
/// shows enough of itself for that to mean something.
fn assert_exact(scene: &mut Scene, what: &str) {
    let picture = frame(scene);
    let reference = cast(scene.objects(), BACKGROUND);
    let wrong = differences_off_the_edges(&picture, &reference);
    assert!(
        wrong.is_empty(),
        "{what}: {} pixels differ from the ray caster off the edges, e.g. {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(8)]
    );
    let covered = reference.id.iter().filter(|&&id| id != 0).count();
    assert!(covered > 500, "{what}: only {covered} pixels covered");
}

/// The scene with the N key pressed `shape` times: 5 is the letter L, 6 the
/// three beams.
fn scene_with(shape: usize) -> Scene {
    let mut scene = Scene::initial();
    for _ in 0..shape {
        scene.apply(SceneCommand::NextSolid);
    }
    scene
}

const LETTER_L: usize = 5;
const BEAMS: usize = 6;

#[test]
fn the_three_beams_are_exact_in_many_orientations() {
    let mut scene = scene_with(BEAMS);
    assert_eq!(scene.solid().name, "three beams");
    for step in 0..40 {
        assert_exact(&mut scene, &format!("beams, step {step}"));
        scene.apply(SceneCommand::Rotate(Axis::Y, positive_if(step % 3 != 0)));
        scene.apply(SceneCommand::Rotate(Axis::X, Sense::Positive));
        if step % 5 == 0 {
            scene.apply(SceneCommand::Rotate(Axis::Z, Sense::Positive));
        }
    }
}

#[test]
fn the_letter_l_is_exact_in_many_orientations() {
    let mut scene = scene_with(LETTER_L);
    assert_eq!(scene.solid().name, "letter L");
    for step in 0..60 {
        assert_exact(&mut scene, &format!("letter L, step {step}"));
        scene.apply(SceneCommand::Rotate(Axis::Y, Sense::Positive));
        if step % 2 == 0 {
            scene.apply(SceneCommand::Rotate(Axis::X, positive_if(step % 4 == 0)));
        }
    }
}

/// The painter's algorithm with faces sorted by the depth of their centres
/// (Ammeraal and Zhang's), far to near, no depth test.
fn painted_by_face_depth(scene: &mut Scene) -> Vec<u8> {
    let mut faces = Vec::new();
    scene.each_visible_face(|visible, colour| {
        faces.push((visible.centre().z, visible.polygon.to_vec(), colour));
    });
    faces.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut image = vec![BACKGROUND; PAGE_PIXELS];
    for (_, polygon, colour) in faces {
        fill_convex_polygon(&polygon, demo::frame::SCREEN_CLIP, |y, x0, x1| {
            let row = y as usize * WIDTH;
            image[row + x0 as usize..row + x1 as usize].fill(colour);
        });
    }
    image
}

#[test]
fn the_painters_order_fails_on_the_beams() {
    let mut scene = scene_with(BEAMS);
    let reference = cast(scene.objects(), BACKGROUND);
    // Sorted by face depth, and whole objects in model order: both wrong at
    // one of the crossings at least, by more than an edge's width.
    let by_face = differences_off_the_edges(&painted_by_face_depth(&mut scene), &reference);
    assert!(by_face.len() > 100, "{} pixels wrong", by_face.len());
    let mut image = Box::new([0u8; PAGE_PIXELS]);
    render_painter(&mut scene, &mut image);
    let by_object = differences_off_the_edges(&image[..], &reference);
    assert!(by_object.len() > 100, "{} pixels wrong", by_object.len());
    // The depth buffer on the same scene: none.
    assert_exact(&mut scene, "beams");
}

#[test]
fn interpenetrating_solids_are_exact() {
    // The cube driven into the octahedron and then through the tetrahedron's
    // orbit: every solid in the cube's place, turned as it goes.
    for shape in 0..7 {
        let mut scene = scene_with(shape);
        scene.apply(SceneCommand::ToggleSeveral);
        scene.apply(SceneCommand::ToggleSpin);
        for step in 0..24 {
            match step % 4 {
                0 => scene.apply(SceneCommand::MoveRight),
                1 => scene.apply(SceneCommand::Away),
                2 => scene.apply(SceneCommand::Rotate(Axis::Z, Sense::Positive)),
                _ => {}
            }
            for _ in 0..5 {
                scene.tick();
            }
            assert_exact(&mut scene, &format!("shape {shape}, step {step}"));
        }
    }
}

#[test]
fn the_cube_inside_the_orbit_is_exact_for_a_whole_orbit() {
    // Where the octahedron's orbit crosses the x axis at the cube's depth:
    // it passes straight through the cube once a revolution.
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleSeveral);
    *scene.primary_mut().object_to_world_mut() = Xform::translation(42.0, 0.0, -100.0);
    scene.apply(SceneCommand::ToggleSpin);
    for frame in 0..360 {
        scene.tick();
        if frame % 3 == 0 {
            assert_exact(&mut scene, &format!("frame {frame}"));
        }
    }
}

#[test]
fn a_thousand_random_poses_of_the_three_object_scene_are_exact() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut random = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for pose in 0..1000 {
        let mut scene = scene_with((random() * 7.0) as usize);
        scene.apply(SceneCommand::ToggleSeveral);
        scene.apply(SceneCommand::ToggleSpin);
        for _ in 0..(random() * 400.0) as usize {
            scene.tick();
        }
        // The primary anywhere the orbits run, turned any way.
        let mut xform = Xform::translation(
            random() * 100.0 - 50.0,
            random() * 70.0 - 35.0,
            -60.0 - random() * 140.0,
        );
        xform.append_rotation_x(random() * 6.3);
        xform.append_rotation_y(random() * 6.3);
        xform.append_rotation_z(random() * 6.3);
        *scene.primary_mut().object_to_world_mut() = xform;
        assert_exact(&mut scene, &format!("pose {pose}"));
    }
}

#[test]
fn the_painters_order_fails_with_the_cube_inside_the_orbit() {
    // The scenes above do test interpenetration: whole objects far to near
    // go wrong there, by more than an edge's width.
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleSeveral);
    *scene.primary_mut().object_to_world_mut() = Xform::translation(42.0, 0.0, -100.0);
    scene.apply(SceneCommand::ToggleSpin);
    let mut image = Box::new([0u8; PAGE_PIXELS]);
    let mut wrong_frames = 0;
    // The octahedron starts a sixth of a revolution past the cube.
    for _ in 0..360 {
        scene.tick();
        render_painter(&mut scene, &mut image);
        let reference = cast(scene.objects(), BACKGROUND);
        if differences_off_the_edges(&image[..], &reference).len() > 20 {
            wrong_frames += 1;
        }
    }
    assert!(wrong_frames > 10, "{wrong_frames} frames wrong");
}

#[test]
fn the_crowd_is_exact() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleCrowd);
    scene.apply(SceneCommand::ToggleSpin);
    assert!(scene.objects().len() >= 50);
    for frame in 0..300 {
        scene.tick();
        if frame % 10 == 0 {
            assert_exact(&mut scene, &format!("crowd, frame {frame}"));
        }
    }
}

#[test]
fn each_convex_solid_alone_is_exact_without_the_depth_test() {
    // One convex solid is drawn without the depth test (see
    // `render_with_depth`); backface removal alone must then be exact.
    for shape in 0..5 {
        let mut scene = scene_with(shape);
        assert!(!demo::frame::needs_depth_test(&mut scene));
        for step in 0..30 {
            assert_exact(&mut scene, &format!("shape {shape}, step {step}"));
            scene.apply(SceneCommand::Rotate(Axis::Y, Sense::Positive));
            scene.apply(SceneCommand::Rotate(Axis::X, positive_if(step % 2 == 0)));
        }
    }
}

/// The positive sense where `positive` holds, else the negative: for
/// alternating turns.
fn positive_if(positive: bool) -> Sense {
    if positive {
        Sense::Positive
    } else {
        Sense::Negative
    }
}
