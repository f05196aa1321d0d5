//! The manual axis through a piped "terminal", and the image-folder camera.

use std::io::{Cursor, Write};
use std::sync::{Arc, Mutex};

use rig::device::{Axis, AxisInfo, Camera};
use rig::drivers::image_folder::ImageFolderCamera;
use rig::drivers::manual::ManualAxis;
use rig::units::AxisUnit;
use rig::{Clock, ClockMode, RigError};

#[derive(Clone, Default)]
struct Screen(Arc<Mutex<Vec<u8>>>);

impl Write for Screen {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Screen {
    fn text(&self) -> String {
        String::from_utf8_lossy(
            &self
                .0
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        )
        .into_owned()
    }
}

fn manual(input: &str) -> (ManualAxis, Screen) {
    let screen = Screen::default();
    let info = AxisInfo {
        role: "normal".into(),
        unit: AxisUnit::Mm,
        travel_min: 0.0,
        travel_max: 25.0,
        max_speed: 1.0,
        resolution: 0.002,
        identity: String::new(),
    };
    let term = Arc::new(Mutex::new((
        Box::new(Cursor::new(input.as_bytes().to_vec())) as Box<dyn std::io::BufRead + Send>,
        Box::new(screen.clone()) as Box<dyn Write + Send>,
    )));
    (ManualAxis::new(info, term), screen)
}

#[tokio::test]
async fn the_operator_confirms_or_corrects_each_setting() {
    // Enter to confirm zero; Enter to confirm 0.420; a typo, then the value actually set.
    let (mut a, screen) = manual("\n\nabc\n0.418 mm\n");
    assert!(matches!(
        a.move_to(0.42, 1.0).await,
        Err(RigError::NotReferenced { .. })
    ));
    a.home().await.expect("home");
    a.move_to(0.42, 1.0).await.expect("confirmed");
    assert!((a.status().await.expect("status").position - 0.42).abs() < 1e-12);
    a.move_to(0.5, 1.0).await.expect("corrected");
    let s = a.status().await.expect("status");
    assert!((s.position - 0.418).abs() < 1e-12 && !s.moving && s.referenced);
    let text = screen.text();
    assert!(
        text.contains("set the normal micrometer to 0.420 mm, then press Enter"),
        "{text}"
    );
    assert!(text.contains("`abc` is not a position"), "{text}");
    // Input closed: a clear error, not a hang.
    let e = a.move_to(1.0, 1.0).await.expect_err("no operator");
    assert!(e.to_string().contains("input closed"), "{e}");
    assert!(matches!(
        a.move_to(30.0, 1.0).await,
        Err(RigError::OutOfTravel { .. })
    ));
}

#[tokio::test]
async fn the_image_folder_replays_frames_in_order() {
    let dir = tempfile::tempdir().expect("tempdir");
    for k in 0..3u8 {
        image::RgbImage::from_pixel(8, 6, image::Rgb([k * 50, 0, 0]))
            .save(dir.path().join(format!("frame_{k:04}.png")))
            .expect("png");
    }
    std::fs::write(dir.path().join("notes.txt"), "not a frame").expect("write");
    let clock = Clock::new(ClockMode::Scaled { scale: 1000.0 });
    let mut cam = ImageFolderCamera::open(dir.path(), 25.0, clock).expect("opens");
    assert_eq!((cam.info().width, cam.info().height), (8, 6));
    for k in 0..3u8 {
        let f = cam.capture().await.expect("frame");
        assert_eq!((f.seq, f.rgb[0]), (k as u64, k * 50));
    }
    let e = cam.capture().await.expect_err("no frames left");
    assert!(e.to_string().contains("repeat"), "{e}");
    cam.repeat = true;
    assert_eq!(cam.capture().await.expect("again").rgb[0], 0);
    // A frame of another size is refused, naming it.
    image::RgbImage::new(4, 4)
        .save(dir.path().join("frame_0003.png"))
        .expect("png");
    let mut cam = ImageFolderCamera::open(
        dir.path(),
        25.0,
        Clock::new(ClockMode::Scaled { scale: 1000.0 }),
    )
    .expect("opens");
    for _ in 0..3 {
        cam.capture().await.expect("frame");
    }
    let e = cam.capture().await.expect_err("size");
    assert!(e.to_string().contains("frame_0003.png"), "{e}");
    // An empty folder is refused with the fix.
    let empty = tempfile::tempdir().expect("tempdir");
    let e = ImageFolderCamera::open(
        empty.path(),
        25.0,
        Clock::new(ClockMode::Scaled { scale: 1000.0 }),
    )
    .err()
    .expect("empty");
    assert!(e.to_string().contains("fix:"), "{e}");
}

/// Reads ../shared/data (skips when absent): the GelSight Mini sequence as a camera.
#[tokio::test]
async fn the_mini_sequence_plays_as_a_camera() {
    let Some(dir) = testkit::shared_data(
        env!("CARGO_MANIFEST_DIR"),
        "gelsight-mini-press",
        "the GelSight Mini sequence as a camera",
    ) else {
        return;
    };
    let mut cam =
        ImageFolderCamera::open(&dir, 60.0, Clock::new(ClockMode::Scaled { scale: 1000.0 }))
            .expect("opens");
    assert_eq!((cam.info().width, cam.info().height), (320, 240));
    let f = cam.capture().await.expect("frame");
    assert_eq!(f.rgb.len(), 320 * 240 * 3);
}
