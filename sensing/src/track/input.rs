//! Reading what `gelrig track` tracks: the frame list of a run directory or of files, the
//! simulator's exact centres, and bounded PNG decoding.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::{Input, TrackFailure};

/// Largest image file read, bytes: a 4K GelSight frame is a few MB as PNG.
const MAX_IMAGE_BYTES: u64 = 256 << 20;
/// Largest image side decoded, pixels.
const MAX_IMAGE_SIDE: u32 = 16_384;

/// Decodes an image file to RGB8. Only a regular file of at most [`MAX_IMAGE_BYTES`] is
/// read (`gelrig track /dev/zero` used to read until memory ran out), and the decoder is
/// bounded in size and memory.
pub fn load_rgb(path: &Path) -> Result<(usize, usize, Vec<u8>), TrackFailure> {
    let mut out = Vec::new();
    let (w, h) = load_rgb_into(path, &mut Vec::new(), &mut out)?;
    Ok((w, h, out))
}

/// [`load_rgb`] into buffers kept from frame to frame: `bytes` receives the file, `out` the
/// pixels. Fresh, a frame's 1.5 MB are mapped and cleared by the kernel on every decode
/// (a fifth of `gelrig track`'s system time on 300 noisy 640×480 PNGs); reused, once.
pub(super) fn load_rgb_into(
    path: &Path,
    bytes: &mut Vec<u8>,
    out: &mut Vec<u8>,
) -> Result<(usize, usize), TrackFailure> {
    use image::ImageDecoder;
    use std::io::Read;
    let read_err = |detail: String| TrackFailure::Read {
        path: path.to_path_buf(),
        detail,
    };
    let meta = fs::metadata(path).map_err(|e| read_err(e.to_string()))?;
    if !meta.is_file() {
        return Err(read_err("not a regular file".into()));
    }
    if meta.len() > MAX_IMAGE_BYTES {
        return Err(read_err(format!(
            "{} bytes, over the {MAX_IMAGE_BYTES} bytes an image may have",
            meta.len()
        )));
    }
    bytes.clear();
    fs::File::open(path)
        .and_then(|f| f.take(MAX_IMAGE_BYTES).read_to_end(bytes))
        .map_err(|e| read_err(e.to_string()))?;
    let decode_err = |detail: String| TrackFailure::Decode {
        path: path.to_path_buf(),
        detail,
    };
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    limits.max_alloc = Some(2 << 30);
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        let cursor = std::io::Cursor::new(bytes.as_slice());
        let decoder = image::codecs::png::PngDecoder::with_limits(cursor, limits.clone())
            .map_err(|e| decode_err(e.to_string()))?;
        if decoder.color_type() == image::ColorType::Rgb8 {
            let (w, h) = decoder.dimensions();
            let len = usize::try_from(decoder.total_bytes())
                .map_err(|_| decode_err("too large to hold".into()))?;
            out.resize(len, 0);
            decoder
                .read_image(out)
                .map_err(|e| decode_err(e.to_string()))?;
            return Ok((w as usize, h as usize));
        }
    }
    // Any other colour type or format: decoded whole, then converted (an RGB8 image moves
    // out without a copy).
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes.as_slice()))
        .with_guessed_format()
        .map_err(|e| decode_err(e.to_string()))?;
    reader.limits(limits);
    let img = reader.decode().map_err(|e| decode_err(e.to_string()))?;
    let rgb = img.into_rgb8();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    *out = rgb.into_raw();
    Ok((w, h))
}

/// One row of `frames.csv`.
#[derive(Debug, Deserialize)]
struct FrameEntry {
    frame: u64,
    step: u32,
    file: String,
}

/// Each step's last frame of a run directory (taken at the end of its settle, where the
/// report reads the step), as (step, frame file), in step order.
pub fn step_last_frames(dir: &Path) -> Result<Vec<(u32, PathBuf)>, TrackFailure> {
    let list = dir.join(rundir::names::FRAMES);
    let bad = |detail: String| TrackFailure::RunDir {
        dir: dir.to_path_buf(),
        detail: format!("frames.csv: {detail}; fix: restore the file from the run's backup"),
    };
    let mut rd = csv::Reader::from_path(&list).map_err(|e| bad(e.to_string()))?;
    let mut last: std::collections::BTreeMap<u32, (u64, String)> = Default::default();
    for row in rd.deserialize::<FrameEntry>() {
        let e = row.map_err(|e| bad(e.to_string()))?;
        let slot = last.entry(e.step).or_insert((e.frame, e.file.clone()));
        if e.frame >= slot.0 {
            *slot = (e.frame, e.file);
        }
    }
    last.into_iter()
        .map(|(step, (_, file))| {
            rundir::write::run_file(dir, &file)
                .map(|p| (step, p))
                .map_err(|d| bad(d.to_string()))
        })
        .collect()
}

/// The reference file, its frame number (when it is one of the input's frames), and the
/// frames to track as (frame number, file).
pub(super) type FrameList = (PathBuf, Option<u64>, Vec<(u64, PathBuf)>);

pub(super) fn frame_list(input: &Input) -> Result<FrameList, TrackFailure> {
    match input {
        Input::ReferenceFree { frames } => {
            let Some((first, rest)) = frames.split_first() else {
                return Err(TrackFailure::Usage {
                    detail: "no frames given; fix: pass the frames to track, first frame first"
                        .into(),
                });
            };
            Ok((
                first.clone(),
                Some(0),
                rest.iter()
                    .enumerate()
                    .map(|(k, p)| (k as u64 + 1, p.clone()))
                    .collect(),
            ))
        }
        Input::Files { reference, frames } => Ok((
            reference.clone(),
            Some(0),
            frames
                .iter()
                .enumerate()
                .map(|(k, p)| (k as u64 + 1, p.clone()))
                .collect(),
        )),
        Input::RunDir { dir, reference } => {
            let list = dir.join(rundir::names::FRAMES);
            let mut rd = csv::Reader::from_path(&list).map_err(|e| TrackFailure::RunDir {
                dir: dir.clone(),
                detail: format!(
                    "cannot read frames.csv ({e}); fix: track a run that captured frames, or \
                     pass --reference REF.png FRAME.png…"
                ),
            })?;
            let mut entries = Vec::new();
            for (line, row) in rd.deserialize::<FrameEntry>().enumerate() {
                let row = row.map_err(|e| TrackFailure::RunDir {
                    dir: dir.clone(),
                    detail: format!(
                        "frames.csv line {}: {e}; fix: restore the file from the run's backup",
                        line + 2
                    ),
                })?;
                entries.push(row);
            }
            if entries.is_empty() {
                return Err(TrackFailure::RunDir {
                    dir: dir.clone(),
                    detail: "frames.csv lists no frames; fix: track a run whose protocol \
                             captures frames"
                        .into(),
                });
            }
            entries.sort_by_key(|e| e.frame);
            let mut files = std::collections::HashMap::new();
            for e in &entries {
                let path = rundir::write::run_file(dir, &e.file).map_err(|d| TrackFailure::RunDir {
                    dir: dir.clone(),
                    detail: format!(
                        "frames.csv, frame {}: {d}; fix: frames.csv must name files under frames/",
                        e.frame
                    ),
                })?;
                files.insert(e.frame, path);
            }
            let file = |e: &FrameEntry| files.get(&e.frame).cloned().unwrap_or_default();
            let list = match reference {
                Some(r) => (
                    r.clone(),
                    None,
                    entries.iter().map(|e| (e.frame, file(e))).collect(),
                ),
                None => {
                    let Some(first) = entries.iter().find(|e| e.step == 0) else {
                        return Err(TrackFailure::RunDir {
                            dir: dir.clone(),
                            detail: "no frame was captured before contact (step 0); fix: add \
                                     `reference_frames: 1` to the protocol's approach, or pass \
                                     --reference with an image of the untouched gel"
                                .into(),
                        });
                    };
                    (
                        file(first),
                        Some(first.frame),
                        entries
                            .iter()
                            .filter(|e| e.frame != first.frame)
                            .map(|e| (e.frame, file(e)))
                            .collect(),
                    )
                }
            };
            Ok(list)
        }
    }
}

/// The simulator's exact centres per frame, if the run has them.
pub(super) fn sim_truth(input: &Input) -> Option<HashMap<u64, Vec<[f64; 2]>>> {
    let Input::RunDir { dir, .. } = input else {
        return None;
    };
    #[derive(Deserialize)]
    struct Row {
        frame: u64,
        id: usize,
        x_px: f64,
        y_px: f64,
    }
    let mut rd = csv::Reader::from_path(dir.join(rundir::names::SIM_MARKERS)).ok()?;
    let mut out: HashMap<u64, Vec<[f64; 2]>> = HashMap::new();
    for row in rd.deserialize::<Row>() {
        let r = row.ok()?;
        let v = out.entry(r.frame).or_default();
        if v.len() <= r.id {
            v.resize(r.id + 1, [f64::NAN; 2]);
        }
        v[r.id] = [r.x_px, r.y_px];
    }
    Some(out)
}

/// A run directory's image scale, mm per px: its sensor's view over the frame size (the
/// larger of the two ratios, as the camera fits the view into the frame). `None` when the
/// run's protocol does not load.
pub(crate) fn run_scale(dir: &Path, width: usize, height: usize) -> Option<f64> {
    let loaded = experiments::load::load(
        &dir.join(rundir::names::PROTOCOL),
        Some(&dir.join(rundir::names::RIG)),
    )
    .ok()?;
    let spec = experiments::protocol::plant_spec(&loaded.protocol, &loaded.compiled).ok()?;
    let s = (spec.view_width_mm / width as f64).max(spec.view_height_mm / height as f64);
    (s.is_finite() && s > 0.0).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::{load_rgb, load_rgb_into};

    /// The reused-buffer path reads what the whole-image path reads, for every colour type a
    /// camera may write (RGB8 straight into the buffer; RGBA, grey and 16-bit converted),
    /// and a buffer that held a larger frame comes back the new frame's size.
    #[test]
    fn every_colour_type_decodes_to_the_same_rgb_into_a_reused_buffer() {
        let dir = tempfile::tempdir().expect("tmp");
        let (w, h) = (7u32, 5u32);
        let rgb =
            image::RgbImage::from_fn(w, h, |x, y| image::Rgb([x as u8 * 30, y as u8 * 40, 200]));
        let cases: Vec<(&str, image::DynamicImage)> = vec![
            ("rgb8", image::DynamicImage::ImageRgb8(rgb.clone())),
            (
                "rgba8",
                image::DynamicImage::ImageRgba8(
                    image::DynamicImage::ImageRgb8(rgb.clone()).into_rgba8(),
                ),
            ),
            (
                "luma8",
                image::DynamicImage::ImageRgb8(rgb.clone()).grayscale(),
            ),
            (
                "rgb16",
                image::DynamicImage::ImageRgb16(
                    image::DynamicImage::ImageRgb8(rgb.clone()).into_rgb16(),
                ),
            ),
        ];
        let (mut bytes, mut out) = (Vec::new(), vec![9u8; 10_000]);
        for (name, img) in cases {
            let path = dir.path().join(format!("{name}.png"));
            img.save(&path).expect("save");
            let want = img.into_rgb8().into_raw();
            let (ww, hh, whole) = load_rgb(&path).expect("whole");
            assert_eq!((ww, hh), (w as usize, h as usize), "{name}");
            assert_eq!(whole, want, "{name}: whole-image path");
            let (rw, rh) = load_rgb_into(&path, &mut bytes, &mut out).expect("reused");
            assert_eq!((rw, rh), (w as usize, h as usize), "{name}");
            assert_eq!(out, want, "{name}: reused buffer");
        }
        // Not an image: the decoder says so, naming the file.
        let junk = dir.path().join("junk.png");
        std::fs::write(&junk, b"\x89PNG\r\n\x1a\nnot really").expect("write");
        let e = load_rgb_into(&junk, &mut bytes, &mut out).expect_err("junk");
        assert!(e.to_string().contains("junk.png"), "{e}");
    }
}
