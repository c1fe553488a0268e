//! The scene's tests: the behaviour of Abrash's original program, then the extras.

use super::*;
use crate::solids::CUBE;
use engine::{Face, Vec3};
use std::vec::Vec;

fn face_normal_and_centre(object: &Object, face: &Face) -> (Vec3, Vec3) {
    let v: [Vec3; 3] = core::array::from_fn(|i| object.view_vertex(face.vertices[i]));
    // Clockwise seen from outside, right-handed: (v0 - v1) x (v2 - v1) points out.
    let normal = (v[0] - v[1]).cross(v[2] - v[1]);
    let count = face.vertices.len() as f64;
    let centre = face
        .vertices
        .iter()
        .fold(Vec3::default(), |sum, &i| sum + object.view_vertex(i))
        * (1.0 / count);
    (normal, centre)
}

#[test]
fn the_initial_cube_projects_to_hand_computed_points() {
    let mut scene = Scene::initial();
    // Front face z = -85: 15/85·320 = 56.47 -> ±56; back face z = -115:
    // 15/115·320 = 41.74 -> ±42.
    let expected = [
        Point::new(216, 64),
        Point::new(202, 78),
        Point::new(216, 176),
        Point::new(202, 162),
        Point::new(104, 64),
        Point::new(118, 78),
        Point::new(104, 176),
        Point::new(118, 162),
    ];
    assert_eq!(scene.primary_mut().screen_vertices(), &expected);
    // Only the front face (vertices 0, 2, 6, 4; colour 9) faces the viewer.
    let mut drawn = std::vec::Vec::new();
    scene.visible_faces(|polygon, colour| drawn.push((polygon.to_vec(), colour)));
    assert_eq!(drawn.len(), 1);
    assert_eq!(drawn[0].1, 9);
}

#[test]
fn screen_culling_agrees_with_the_view_space_dot_product_test() {
    // Rost's test: a face is visible when its outward normal points toward
    // the eye, normal · (eye − point on face) > 0, with the eye at the origin.
    let mut seed = 0x1234_5678_9abc_def1u64;
    let mut random = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed % 10_000) as f64 / 10_000.0
    };
    let (mut checked, mut skipped) = (0, 0);
    for _ in 0..2000 {
        let mut xform = Xform::translation(
            random() * 60.0 - 30.0,
            random() * 60.0 - 30.0,
            -60.0 - random() * 150.0,
        );
        xform.append_rotation_x(random() * 2.0 * PI);
        xform.append_rotation_y(random() * 2.0 * PI);
        xform.append_rotation_z(random() * 2.0 * PI);
        let mut cube = Object::new(&CUBE, xform);
        let mut drawn = [false; 6];
        let mut index = 0;
        let screen: std::vec::Vec<Point> = cube.screen_vertices().to_vec();
        for (i, face) in CUBE.faces.iter().enumerate() {
            let polygon: std::vec::Vec<Point> = face.vertices.iter().map(|&v| screen[v]).collect();
            drawn[i] = engine::is_front_facing(&polygon);
        }
        cube.visible_faces(|_, _| index += 1);
        assert_eq!(index, drawn.iter().filter(|&&d| d).count());
        for (i, face) in CUBE.faces.iter().enumerate() {
            let (normal, centre) = face_normal_and_centre(&cube, face);
            let facing = normal.dot(-centre) / (normal.length() * centre.length());
            // Nearly edge-on faces project to slivers a pixel or two wide,
            // where integer rounding may legitimately decide either way.
            if facing.abs() < 0.02 {
                skipped += 1;
                continue;
            }
            checked += 1;
            assert_eq!(drawn[i], facing > 0.0, "face {i} at cos {facing}");
        }
    }
    assert!(checked > 11_000, "checked {checked}, skipped {skipped}");
}

#[test]
fn commands_move_and_turn_like_abrashs_program() {
    let mut scene = Scene::initial();
    for (command, expected) in [
        (SceneCommand::MoveLeft, Vec3::new(-3.0, 0.0, -100.0)),
        (SceneCommand::MoveUp, Vec3::new(-3.0, 3.0, -100.0)),
        (SceneCommand::MoveRight, Vec3::new(0.0, 3.0, -100.0)),
        (SceneCommand::MoveDown, Vec3::new(0.0, 0.0, -100.0)),
        (SceneCommand::Away, Vec3::new(0.0, 0.0, -103.0)),
        (SceneCommand::Toward, Vec3::new(0.0, 0.0, -100.0)),
    ] {
        scene.apply(command);
        assert_eq!(
            scene.primary().object_to_world().translation_part(),
            expected,
            "{command:?}"
        );
    }
    scene.apply(SceneCommand::Rotate(Axis::Y, Sense::Positive));
    let mut expected = Xform::translation(0.0, 0.0, -100.0);
    expected.append_rotation_y(ROTATION_STEP);
    assert_eq!(scene.primary().object_to_world(), &expected);
}

#[test]
fn toward_stops_at_the_near_limit() {
    let mut scene = Scene::initial();
    for _ in 0..100 {
        scene.apply(SceneCommand::Toward);
    }
    let z = scene.primary().object_to_world().translation_part().z;
    assert!((NEAREST_Z..NEAREST_Z + MOVE_STEP).contains(&z), "z = {z}");
}

#[test]
fn vertices_are_projected_only_when_something_moved() {
    let mut scene = Scene::initial();
    scene.visible_faces(|_, _| {});
    scene.visible_faces(|_, _| {});
    assert_eq!(scene.primary().projections(), 1);
    scene.tick(); // not spinning: nothing moves
    scene.visible_faces(|_, _| {});
    assert_eq!(scene.primary().projections(), 1);
    scene.apply(SceneCommand::MoveLeft);
    scene.visible_faces(|_, _| {});
    assert_eq!(scene.primary().projections(), 2);
}

#[test]
fn spin_is_on_at_boot_and_reset_restores_the_initial_state() {
    let mut scene = Scene::new();
    assert!(scene.spinning());
    for _ in 0..500 {
        scene.tick();
    }
    scene.apply(SceneCommand::MoveLeft);
    scene.apply(SceneCommand::Reset);
    assert!(!scene.spinning());
    assert_eq!(
        scene.primary().object_to_world(),
        Scene::initial().primary().object_to_world()
    );
}

fn colours_drawn(scene: &mut Scene) -> std::vec::Vec<u8> {
    let mut colours = std::vec::Vec::new();
    scene.visible_faces(|_, colour| colours.push(colour));
    colours
}

#[test]
fn lighting_shades_each_face_by_the_angle_to_the_light() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleLighting);
    // Only the front face (bright blue, ramp 0) shows; its normal is
    // (0, 0, 1) and the light comes from (-1, 1, 1)/√3: intensity
    // 0.25 + 0.75/√3 = 0.683, level round(0.683 · 31) = 21.
    assert_eq!(colours_drawn(&mut scene), [16 + 21]);
    // Three steps right put the light straight above the line of sight:
    // 0.25 + 0.75 · cos 35.26° = 0.862, level 27.
    for _ in 0..3 {
        scene.apply(SceneCommand::TurnLight(LightTurn::Right));
    }
    assert_eq!(colours_drawn(&mut scene), [16 + 27]);
    // Turned away behind the cube, only the ambient share is left: 0.25,
    // level 8 (7.75 rounded).
    for _ in 0..12 {
        scene.apply(SceneCommand::TurnLight(LightTurn::Right));
    }
    for _ in 0..3 {
        scene.apply(SceneCommand::TurnLight(LightTurn::Down));
    }
    assert_eq!(colours_drawn(&mut scene), [16 + 8]);
    scene.apply(SceneCommand::ToggleLighting);
    assert_eq!(colours_drawn(&mut scene), [9], "flat colours again");
}

#[test]
fn n_puts_each_solid_in_the_cubes_place_in_turn() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::MoveLeft);
    let place = *scene.primary().object_to_world();
    let mut seen = std::vec::Vec::new();
    for _ in 0..crate::solids::SHAPES.len() {
        scene.apply(SceneCommand::NextSolid);
        seen.push(scene.solid().name);
        assert!(core::ptr::eq(scene.primary().model(), scene.solid().model));
        assert_eq!(scene.primary().object_to_world(), &place);
        assert!(!colours_drawn(&mut scene).is_empty());
    }
    assert_eq!(
        seen,
        [
            "tetrahedron",
            "octahedron",
            "dodecahedron",
            "icosahedron",
            "letter L",
            "three beams",
            "cube"
        ]
    );
}

#[test]
fn reset_returns_to_the_starting_scene_from_every_extra() {
    let mut scene = Scene::new();
    for command in [
        SceneCommand::ToggleLighting,
        SceneCommand::TurnLight(LightTurn::Up),
        SceneCommand::NextSolid,
        SceneCommand::ToggleSeveral,
    ] {
        scene.apply(command);
    }
    scene.tick();
    scene.apply(SceneCommand::Reset);
    assert!(!scene.lighting() && !scene.several() && !scene.spinning());
    assert_eq!(scene.solid().name, "cube");
    assert_eq!(scene.light(), &default_light());
    assert_eq!(scene.objects().len(), 1);
    assert_eq!(colours_drawn(&mut scene), [9]);
}

#[test]
fn several_objects_are_drawn_far_to_near() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleSeveral);
    // The tetrahedron circles 180 units away, the octahedron starts in
    // front of the cube's right side (about 67 units away).
    let (order, count) = scene.drawing_order();
    assert_eq!(&order[..count], [2, 0, 1]);
    for _ in 0..100 {
        scene.apply(SceneCommand::Away);
    }
    let (order, count) = scene.drawing_order();
    assert_eq!(&order[..count], [0, 2, 1]);
    scene.apply(SceneCommand::ToggleSeveral);
    assert_eq!(scene.drawing_order().1, 1);
}

/// Each object alone, as colour indices (0 where it does not cover).
fn picture_of(object: &Object) -> std::vec::Vec<u8> {
    let mut object = object.clone();
    let mut picture = std::vec![0u8; 320 * 240];
    let clip = engine::ClipRect {
        x0: 0,
        y0: 0,
        x1: 320,
        y1: 240,
    };
    object.visible_faces(|polygon, colour| {
        engine::fill_convex_polygon(polygon, clip, |y, x0, x1| {
            let row = y as usize * 320;
            picture[row + x0 as usize..row + x1 as usize].fill(colour);
        });
    });
    picture
}

#[test]
fn where_objects_overlap_the_nearer_one_shows() {
    let mut scene = Scene::new();
    scene.apply(SceneCommand::ToggleSeveral);
    let mut overlapping_pixels = 0;
    for frame in 0..720 {
        scene.tick();
        if frame % 8 != 0 {
            continue;
        }
        let mut frame_picture = std::vec![0u8; 320 * 240];
        let clip = crate::screen::SCREEN_CLIP;
        scene.visible_faces(|polygon, colour| {
            engine::fill_convex_polygon(polygon, clip, |y, x0, x1| {
                let row = y as usize * 320;
                frame_picture[row + x0 as usize..row + x1 as usize].fill(colour);
            });
        });
        // Nearest first.
        let mut alone: std::vec::Vec<(f64, std::vec::Vec<u8>)> = scene
            .objects()
            .iter()
            .map(|object| (object.position().length(), picture_of(object)))
            .collect();
        alone.sort_by(|a, b| a.0.total_cmp(&b.0));
        for pixel in 0..320 * 240 {
            let covering: std::vec::Vec<u8> = alone
                .iter()
                .map(|(_, picture)| picture[pixel])
                .filter(|&colour| colour != 0)
                .collect();
            overlapping_pixels += usize::from(covering.len() > 1);
            let expected = covering.first().copied().unwrap_or(0);
            assert_eq!(
                frame_picture[pixel], expected,
                "frame {frame}, pixel {pixel}"
            );
        }
    }
    assert!(
        overlapping_pixels > 10_000,
        "only {overlapping_pixels} overlaps"
    );
}

#[test]
fn only_the_objects_that_moved_are_projected_again() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleSeveral);
    let projections = |scene: &Scene| -> std::vec::Vec<u64> {
        scene.objects().iter().map(Object::projections).collect()
    };
    scene.visible_faces(|_, _| {});
    assert_eq!(projections(&scene), [1, 1, 1]);
    scene.visible_faces(|_, _| {});
    scene.tick(); // spin is off: nothing moves
    scene.visible_faces(|_, _| {});
    assert_eq!(projections(&scene), [1, 1, 1]);
    scene.apply(SceneCommand::MoveLeft);
    scene.visible_faces(|_, _| {});
    assert_eq!(projections(&scene), [2, 1, 1], "only the cube moved");
    scene.apply(SceneCommand::ToggleSpin);
    scene.tick();
    scene.visible_faces(|_, _| {});
    assert_eq!(projections(&scene), [3, 2, 2], "everything moves");
    scene.apply(SceneCommand::ToggleSeveral);
    scene.tick();
    scene.visible_faces(|_, _| {});
    scene.apply(SceneCommand::ToggleSeveral);
    scene.visible_faces(|_, _| {});
    assert_eq!(
        projections(&scene),
        [4, 2, 2],
        "hidden satellites neither move nor get projected"
    );
}

#[test]
fn the_satellites_never_come_near_the_viewer_and_keep_apart() {
    let mut scene = Scene::new();
    scene.apply(SceneCommand::ToggleSeveral);
    let initial_cube = Scene::initial().primary().position();
    for _ in 0..2000 {
        scene.tick();
        let objects = scene.objects();
        let (a, b) = (objects[1].position(), objects[2].position());
        for position in [a, b] {
            assert!(position.z + 13.0 < NEAREST_Z, "{position:?}");
            assert!((position - initial_cube).length() > 26.0 + 13.0);
        }
        assert!((a - b).length() > 26.0, "{a:?} {b:?}");
    }
}

#[test]
fn x_shows_a_crowd_of_more_than_fifty_solids_and_r_takes_it_away() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleCrowd);
    assert!(scene.crowd());
    assert_eq!(scene.objects().len(), 1 + SATELLITES + CROWD);
    const { assert!(CROWD >= 50) };
    let counts = scene.visible_faces(|_, _| {});
    assert!(counts.drawn > 200, "{counts:?}");
    scene.apply(SceneCommand::ToggleCrowd);
    assert_eq!(scene.objects().len(), 1);
    scene.apply(SceneCommand::ToggleCrowd);
    scene.apply(SceneCommand::Reset);
    assert!(!scene.crowd());
    assert_eq!(scene.objects().len(), 1);
}

#[test]
fn each_member_of_the_crowd_is_projected_only_on_the_frames_it_moves() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleCrowd);
    scene.apply(SceneCommand::ToggleSpin);
    scene.visible_faces(|_, _| {});
    let first = 1 + SATELLITES;
    for frame in 1..=24u64 {
        scene.tick();
        scene.visible_faces(|_, _| {});
        for (member, object) in scene.objects()[first..].iter().enumerate() {
            // Member k moves every (k % 4 + 1)-th frame.
            let period = member as u64 % 4 + 1;
            assert_eq!(
                object.projections(),
                1 + frame / period,
                "member {member}, frame {frame}"
            );
        }
    }
    // The primary and the satellites move every frame.
    assert!(scene.objects()[..first]
        .iter()
        .all(|o| o.projections() == 25));
}

#[test]
fn members_of_the_crowd_pass_through_each_other() {
    // Else the crowd would not need the depth test: some pair of neighbours
    // must come closer than their size within a few hundred frames.
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleCrowd);
    scene.apply(SceneCommand::ToggleSpin);
    let first = 1 + SATELLITES;
    let mut closest = f64::INFINITY;
    for _ in 0..400 {
        scene.tick();
        let objects = &scene.objects()[first..];
        for (i, a) in objects.iter().enumerate() {
            for b in &objects[i + 1..] {
                closest = closest.min((a.position() - b.position()).length());
            }
        }
    }
    assert!(closest < 12.0, "closest {closest}");
}

/// The faces handed out are the faces `each_visible_face` walks, in its
/// order and colours, grouped by object; the painter's order is
/// `drawing_order`'s; the counts and the small-solids flag are the scene's.
/// One list serves every frame of every scene, with the lighting, the light
/// and the solid changed on the way, so faces it keeps from the last frame
/// must be the ones found afresh.
#[test]
fn the_faces_handed_out_are_the_faces_the_scene_walks() {
    let mut list = std::boxed::Box::new(SceneFaces::new());
    let setups: [&[SceneCommand]; 4] = [
        &[],
        &[SceneCommand::ToggleSeveral, SceneCommand::ToggleLighting],
        &[SceneCommand::NextSolid; 5], // the letter L, not convex
        &[SceneCommand::ToggleCrowd, SceneCommand::ToggleLighting],
    ];
    for commands in setups {
        let mut scene = Scene::new();
        for &command in commands {
            scene.apply(command);
        }
        for frame in 0..40 {
            match frame {
                10 | 25 => scene.apply(SceneCommand::ToggleLighting),
                15 | 30 => scene.apply(SceneCommand::TurnLight(LightTurn::Left)),
                20 => scene.apply(SceneCommand::NextSolid),
                _ => {}
            }
            scene.tick();
            let mut walked = std::vec::Vec::new();
            let counts = scene.each_visible_face(|visible, colour| {
                walked.push((visible.polygon.to_vec(), colour, visible.depth_plane()));
            });
            let mut by_object = std::vec::Vec::new();
            for object in scene.objects_mut() {
                let mut faces = std::vec::Vec::new();
                object.each_visible_face(|visible| faces.push(visible.polygon.to_vec()));
                by_object.push(faces);
            }
            let (order, count) = scene.drawing_order();
            let crowd = scene.crowd();
            let convex: std::vec::Vec<bool> = scene
                .objects()
                .iter()
                .map(|object| {
                    SHAPES
                        .iter()
                        .any(|s| core::ptr::eq(s.model, object.model()) && s.convex)
                })
                .collect();
            let faces = scene.faces(&mut list);
            let context = std::format!("{commands:?}, frame {frame}");
            assert_eq!(faces.counts(), counts, "{context}");
            assert_eq!(faces.small_solids(), crowd, "{context}");
            let listed: std::vec::Vec<_> = faces
                .all()
                .iter()
                .map(|face| (face.polygon().to_vec(), face.colour, face.depth_plane))
                .collect();
            assert_eq!(listed, walked, "{context}");
            assert_eq!(faces.objects().len(), count, "{context}");
            for (index, object) in faces.objects().iter().enumerate() {
                let polygons: std::vec::Vec<_> = faces
                    .of(object)
                    .iter()
                    .map(|face| face.polygon().to_vec())
                    .collect();
                assert_eq!(polygons, by_object[index], "{context}, object {index}");
                assert_eq!(object.convex, convex[index], "{context}, object {index}");
                assert!(object.bounds.is_some(), "{context}, object {index}");
            }
            let painted: std::vec::Vec<_> = faces.far_to_near().collect();
            for (slot, &index) in order[..count].iter().enumerate() {
                assert_eq!(
                    painted[slot],
                    faces.of(&faces.objects()[index]),
                    "{context}"
                );
            }
        }
    }
}

/// The face list has room for the most faces the scene can show: every
/// object's model's faces, whatever solid is in the cube's place.
#[test]
fn the_face_list_holds_every_face_of_every_object() {
    for shape in 0..SHAPES.len() {
        let mut scene = Scene::initial();
        for _ in 0..shape {
            scene.apply(SceneCommand::NextSolid);
        }
        scene.apply(SceneCommand::ToggleCrowd);
        assert_eq!(scene.objects().len(), MAX_OBJECTS);
        let faces: usize = scene
            .objects()
            .iter()
            .map(|object| object.model().faces.len())
            .sum();
        assert!(faces <= MAX_FACES, "{faces} faces with shape {shape}");
    }
    // And no more than that: the largest shape's case fills it exactly.
    let most = SHAPES.iter().map(|s| s.model.faces.len()).max().unwrap();
    let largest = SHAPES
        .iter()
        .position(|s| s.model.faces.len() == most)
        .unwrap();
    let mut scene = Scene::initial();
    for _ in 0..largest {
        scene.apply(SceneCommand::NextSolid);
    }
    scene.apply(SceneCommand::ToggleCrowd);
    let faces: usize = scene
        .objects()
        .iter()
        .map(|object| object.model().faces.len())
        .sum();
    assert_eq!(faces, MAX_FACES);
}

/// The drawing order's sort, started from any order (the last frame's),
/// gives the order that farthest first, and by index among equals, gives:
/// the straightforward sort's.
#[test]
fn the_drawing_order_does_not_depend_on_where_its_sort_starts() {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move |below: u64| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state % below
    };
    for round in 0..2_000 {
        let count = 1 + next(MAX_OBJECTS as u64) as usize;
        // Few distinct distances, so that ties are common; -0.0 and 0.0
        // and a NaN too, which `total_cmp` orders.
        let distance: Vec<f64> = (0..count)
            .map(|_| match next(12) {
                0 => -0.0,
                1 => f64::NAN,
                n => n as f64 * 7.5,
            })
            .collect();
        let mut expected: Vec<usize> = (0..count).collect();
        expected.sort_by(|&a, &b| distance[b].total_cmp(&distance[a]).then(a.cmp(&b)));
        // A shuffled start, or on odd rounds the answer itself nearly:
        // two neighbours swapped, as a frame's motion does.
        let mut order: Vec<usize> = if round % 2 == 0 {
            let mut shuffled: Vec<usize> = (0..count).collect();
            for i in (1..count).rev() {
                shuffled.swap(i, next(i as u64 + 1) as usize);
            }
            shuffled
        } else {
            let mut near = expected.clone();
            if count > 1 {
                let i = next(count as u64 - 1) as usize;
                near.swap(i, i + 1);
            }
            near
        };
        super::sort_far_to_near(&mut order, |index| distance[index]);
        assert_eq!(order, expected, "{distance:?}");
    }
}

/// A scene's order, sorted from the last frame's, is a fresh scene's.
#[test]
fn the_drawing_order_after_frames_is_the_order_from_scratch() {
    let mut scene = Scene::initial();
    scene.apply(SceneCommand::ToggleCrowd);
    for _ in 0..40 {
        scene.tick();
        scene.visible_faces(|_, _| {});
        let mut fresh = scene.clone();
        fresh.last_order = ([0; MAX_OBJECTS], 0);
        assert_eq!(scene.drawing_order(), fresh.drawing_order());
    }
}
