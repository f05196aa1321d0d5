//! Time of one simulated GelSight frame at 640×480 (issue 3 target: ≤ 5 ms): shading of the
//! surface slope, 288 markers at displaced positions with blurred edges, noise. The field
//! itself is the `mechanics` bench `field/256`.

use criterion::{Criterion, criterion_group, criterion_main};
use mechanics::contact::Contact;
use mechanics::response::{ContactModel, ModelSpec, Quality, State};
use mechanics::{Indenter, Layer};
use simbench::{MarkerLayout, PlantSpec, Renderer, SurfaceView};

fn spec(markers: MarkerLayout, view: (f64, f64), h: f64, indenter: Indenter) -> PlantSpec {
    PlantSpec {
        contact: Contact::new(
            Layer {
                width_mm: 125.0,
                length_mm: 70.0,
                thickness_mm: h,
            },
            mechanics::geometry::presets::box_material(),
            indenter,
        )
        .expect("valid contact"),
        markers,
        view_width_mm: view.0,
        view_height_mm: view.1,
        object_mass_g: None,
        max_depth_mm: 0.84,
        kinetic_friction: 0.54,
        quality: Quality::default(),
    }
}

fn render(c: &mut Criterion) {
    let mut group = c.benchmark_group("frame_640x480");
    let cases = [
        (
            "box_grid_288",
            spec(
                MarkerLayout::Grid {
                    columns: 18,
                    rows: 16,
                    spacing_mm: 2.52,
                    diameter_mm: 1.4,
                },
                (45.36, 40.32),
                4.2,
                Indenter::FlatCircle { diameter_mm: 9.5 },
            ),
            0.84,
        ),
        (
            "portable_triangles",
            spec(
                MarkerLayout::Random {
                    spacing_mm: 2.0,
                    size_mm: 0.7,
                },
                (20.0, 15.0),
                2.0,
                Indenter::FlatCircle { diameter_mm: 12.5 },
            ),
            0.3,
        ),
    ];
    for (name, s, depth) in cases {
        let mut model = ContactModel::build(ModelSpec {
            contact: s.contact.clone(),
            max_depth_mm: depth,
            shear: false,
            twist: false,
            field_view_mm: Some((s.view_width_mm, s.view_height_mm)),
            pressing_friction: false,
            quality: Quality::default(),
        })
        .expect("model");
        let field = model
            .field(State {
                depth_mm: depth,
                shear_n: 0.0,
                torque_nmm: 0.0,
            })
            .expect("field");
        let view = SurfaceView {
            field,
            centre_mm: (0.0, 0.0),
            rotation_rad: 0.0,
        };
        let renderer = Renderer::new(&s, 640, 480);
        let mut seq = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                seq += 1;
                renderer.render(Some(&view), seq)
            })
        });
    }
    group.finish();
}

/// PNG encoding of a rendered portable frame (what the recorder's frame writer does per
/// frame): the default deflate level against the fast one it uses. The sizes are printed.
fn encode(c: &mut Criterion) {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let s = spec(
        MarkerLayout::Random {
            spacing_mm: 2.0,
            size_mm: 0.7,
        },
        (20.0, 15.0),
        2.0,
        Indenter::FlatCircle { diameter_mm: 12.5 },
    );
    let (rgb, _) = Renderer::new(&s, 640, 480).render(None, 7);
    let mut group = c.benchmark_group("png_640x480");
    for (name, comp, filter) in [
        ("default", CompressionType::Default, FilterType::Adaptive),
        ("fast_sub", CompressionType::Fast, FilterType::Sub),
    ] {
        let once = |out: &mut Vec<u8>| {
            PngEncoder::new_with_quality(out, comp, filter)
                .write_image(&rgb, 640, 480, image::ExtendedColorType::Rgb8)
                .expect("encode");
        };
        let mut probe = Vec::new();
        once(&mut probe);
        eprintln!("png_640x480/{name}: {} bytes", probe.len());
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut out = Vec::with_capacity(rgb.len());
                once(&mut out);
                out
            })
        });
    }
    // What the recorder did before: `RgbImage::write_to(…, ImageFormat::Png)`.
    let img = image::RgbImage::from_raw(640, 480, rgb.clone()).expect("frame");
    let mut probe = std::io::Cursor::new(Vec::new());
    img.write_to(&mut probe, image::ImageFormat::Png)
        .expect("encode");
    eprintln!("png_640x480/write_to: {} bytes", probe.get_ref().len());
    group.bench_function("write_to", |b| {
        b.iter(|| {
            let mut out = std::io::Cursor::new(Vec::with_capacity(rgb.len()));
            img.write_to(&mut out, image::ImageFormat::Png)
                .expect("encode");
            out
        })
    });
    group.finish();
}

criterion_group!(benches, render, encode);
criterion_main!(benches);
