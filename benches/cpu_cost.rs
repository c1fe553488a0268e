//! What a frame costs the CPU as the scene grows, on the host.
//!
//! `cargo bench --bench cpu_cost` spins scenes of 10 to 5,000 faces (cubes,
//! tetrahedra and icosahedra in a grid over the screen, in layers one behind
//! the other, every object turning every frame so every vertex is
//! transformed and projected again) and times, per frame: the 3-D work and
//! the depth-tested scan conversion into the RAM frame (`render_faces_with_
//! depth`), and bringing a page up to date from it on the software VGA
//! (whose time is the model's, not a real VGA's). It prints a table and a
//! machine-readable SUMMARY line.
//!
//! Host figures only: they show how the cost grows with the scene, not what
//! the kernel takes on a given PC (see the kernel's `bench` boot option).

use demo::frame::{render_faces_with_depth, BACKGROUND};
use demo::solids::{CUBE, ICOSAHEDRON, TETRAHEDRON};
use engine::{DepthBuffer, FaceCounts, Model, Object, Xform};
use modex::soft::SoftVga;
use modex::{ModeX, Page, PageSpans, PAGE_PIXELS};
use std::hint::black_box;
use std::time::{Duration, Instant};

const SIZES: [usize; 7] = [10, 50, 100, 500, 1000, 2000, 5000];
const COLUMNS: usize = 16;
const ROWS: usize = 12;

/// Objects whose faces add up to `faces`: icosahedra (20 faces) while they
/// fit, then cubes (6) and tetrahedra (4) for the rest.
fn models_for(faces: usize) -> Vec<&'static Model> {
    let mut models = vec![&ICOSAHEDRON; faces / 20];
    let mut left = faces % 20;
    while left >= 6 && left != 8 {
        models.push(&CUBE);
        left -= 6;
    }
    while left >= 4 {
        models.push(&TETRAHEDRON);
        left -= 4;
    }
    assert_eq!(left, 0, "{faces} faces cannot be made of these solids");
    models
}

/// Object `index` of the grid: 16 × 12 over the screen, each full layer
/// 40 units behind the last, small enough that neighbours just touch.
fn place(index: usize) -> Xform {
    let (column, row, layer) = (
        index % COLUMNS,
        index / COLUMNS % ROWS,
        index / (COLUMNS * ROWS),
    );
    let z = -200.0 - 40.0 * layer as f64;
    let half_width = -z * 160.0 / 320.0;
    let half_height = -z * 120.0 / 320.0;
    let x = ((column as f64 + 0.5) / COLUMNS as f64 * 2.0 - 1.0) * half_width;
    let y = ((row as f64 + 0.5) / ROWS as f64 * 2.0 - 1.0) * half_height;
    let mut xform = Xform::translation(x, y, z);
    xform.append_rotation_y(index as f64 * 0.37);
    Xform::concat(&xform, &Xform::scaling(0.3))
}

struct Measured {
    faces: usize,
    objects: usize,
    drawn: f64,
    render: Duration,
    update: Duration,
    frames: u32,
}

fn measure(faces: usize) -> Measured {
    let models = models_for(faces);
    let mut objects: Vec<Object> = models
        .iter()
        .enumerate()
        .map(|(i, &model)| Object::new(model, place(i)))
        .collect();
    let mut image = Box::new([BACKGROUND; PAGE_PIXELS]);
    let mut depths = Box::new(DepthBuffer::new());
    let mut shadow = Box::new([BACKGROUND; PAGE_PIXELS]);
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    let frames = (200_000 / faces.max(100)).clamp(20, 600) as u32;
    let (mut render, mut update, mut drawn) = (Duration::ZERO, Duration::ZERO, 0u64);
    for _ in 0..frames {
        for object in &mut objects {
            object.object_to_world_mut().append_rotation_y(0.02);
            object.object_to_world_mut().append_rotation_x(0.01);
        }
        let start = Instant::now();
        let counts =
            render_faces_with_depth(&mut image, &mut PageSpans::all(), &mut depths, |draw| {
                let mut counts = FaceCounts::default();
                for object in &mut objects {
                    counts +=
                        object.each_visible_face(|visible| draw(visible, visible.face.colour));
                }
                counts
            });
        let rendered = Instant::now();
        ModeX::new(&mut *soft).update_page(
            Page::One,
            &mut shadow,
            black_box(&image),
            &PageSpans::all(),
        );
        update += rendered.elapsed();
        render += rendered - start;
        drawn += u64::from(counts.drawn);
        assert_eq!((counts.drawn + counts.culled) as usize, faces);
    }
    Measured {
        faces,
        objects: objects.len(),
        drawn: drawn as f64 / f64::from(frames),
        render,
        update,
        frames,
    }
}

fn main() {
    println!("CPU time per frame on this host, every object turning every frame:");
    println!(
        "{:>6} {:>8} {:>8} {:>14} {:>14} {:>8}",
        "faces", "objects", "drawn", "render µs", "update µs", "frames"
    );
    let mut results = Vec::new();
    for faces in SIZES {
        let m = measure(faces);
        let per = |d: Duration| d.as_secs_f64() * 1e6 / f64::from(m.frames);
        println!(
            "{:>6} {:>8} {:>8.0} {:>14.1} {:>14.1} {:>8}",
            m.faces,
            m.objects,
            m.drawn,
            per(m.render),
            per(m.update),
            m.frames
        );
        results.push(format!(
            "{}:{:.1}:{:.1}",
            m.faces,
            per(m.render),
            per(m.update)
        ));
    }
    println!("\nrender: transform, project, cull and depth-tested scan conversion into RAM");
    println!("update: changed pixels onto the software VGA's page (the model's time)");
    println!("SUMMARY faces:render_us:update_us {}", results.join(" "));
}
