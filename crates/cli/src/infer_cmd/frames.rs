//! Reading a camera's frames and pose for `umpnet infer`: RGB and depth
//! files (PNG, .npy) and the camera (flags or camera.json), each checked
//! before it is used, so that a bad file is refused by name.
use super::InferArgs;
use crate::usage;
use anyhow::{Context, Result};
use std::path::Path;
use umpnet_policy::observation::OwnedFrame;

/// Largest image or depth file `infer` reads (a 4K float64 depth is 70 MB).
const MAX_IMAGE_BYTES: u64 = 256 << 20;

/// An input file checked before it is opened: a regular file within `max`
/// bytes (a FIFO would block, a device never end).
fn input(path: &Path, max: u64) -> Result<u64> {
    umpnet_sim::fsio::check_input(path, max).map_err(|e| usage(e.to_string()))
}

/// Checks that a .npy header's 2-D shape and dtype account for the file's
/// size exactly, before a reader allocates what the header claims.
fn check_npy_header(path: &Path, size: u64) -> Result<()> {
    use std::io::Read;
    let bad = |what: String| anyhow::anyhow!("{}: {what}", path.display());
    let mut head = Vec::new();
    std::fs::File::open(path)
        .with_context(|| format!("reading {}", path.display()))?
        .take(64 << 10)
        .read_to_end(&mut head)
        .with_context(|| format!("reading {}", path.display()))?;
    if head.get(..6) != Some(b"\x93NUMPY".as_slice()) {
        return Err(bad("not a .npy file (no \\x93NUMPY magic)".into()));
    }
    let (len, start) = match head.get(6) {
        Some(1) => (
            head.get(8..10)
                .and_then(|b| <[u8; 2]>::try_from(b).ok())
                .map(|b| u64::from(u16::from_le_bytes(b))),
            10u64,
        ),
        Some(2 | 3) => (
            head.get(8..12)
                .and_then(|b| <[u8; 4]>::try_from(b).ok())
                .map(|b| u64::from(u32::from_le_bytes(b))),
            12u64,
        ),
        _ => (None, 0),
    };
    let Some(len) = len else {
        return Err(bad("unknown .npy version".into()));
    };
    let header = head
        .get(start as usize..(start + len) as usize)
        .map(|h| String::from_utf8_lossy(h).into_owned())
        .ok_or_else(|| bad("header longer than the file".into()))?;
    let item: u64 = if header.contains("f8") {
        8
    } else if header.contains("f4") {
        4
    } else if header.contains("u2") {
        2
    } else {
        return Err(bad(
            "dtype is not float32, float64 or uint16; expected a depth array".into(),
        ));
    };
    let shape: Vec<u64> = header
        .split_once("'shape':")
        .and_then(|(_, rest)| rest.split_once('(')?.1.split_once(')'))
        .map(|(dims, _)| {
            dims.split(',')
                .filter(|d| !d.trim().is_empty())
                .filter_map(|d| d.trim().parse().ok())
                .collect()
        })
        .unwrap_or_default();
    let [h, w] = shape[..] else {
        return Err(bad(format!(
            "shape {shape:?}: expected a 2-D (height, width) array"
        )));
    };
    let data = h
        .checked_mul(w)
        .and_then(|n| n.checked_mul(item))
        .and_then(|n| n.checked_add(start + len));
    if data != Some(size) {
        return Err(bad(format!(
            "the header says {h}x{w} values of {item} bytes, but the file holds {size} bytes"
        )));
    }
    Ok(())
}

/// A 2-D depth array from a .npy file: float32 or float64 metres, or uint16
/// units of `scale` metres.
fn read_npy(path: &Path, scale: f32) -> Result<(usize, usize, Vec<f32>)> {
    let size = input(path, MAX_IMAGE_BYTES)?;
    check_npy_header(path, size)?;
    use ndarray::Array2;
    use ndarray_npy::{ReadNpyError, ReadNpyExt};
    let open = || {
        std::fs::File::open(path)
            .map(std::io::BufReader::new)
            .with_context(|| format!("reading {}", path.display()))
    };
    let bad = |e: ReadNpyError| {
        anyhow::anyhow!(
            "{}: not a readable 2-D .npy depth array (float32/float64 metres or uint16 scaled): {e}",
            path.display()
        )
    };
    // Each dtype in turn: a mismatch is reported as a wrong descriptor, and
    // only then is the next one tried.
    let wrong_type = |e: &ReadNpyError| matches!(e, ReadNpyError::WrongDescriptor(_));
    let values: Array2<f32> = match Array2::<f32>::read_npy(open()?) {
        Ok(a) => a,
        Err(e) if wrong_type(&e) => match Array2::<f64>::read_npy(open()?) {
            Ok(a) => a.mapv(|v| v as f32),
            Err(e) if wrong_type(&e) => Array2::<u16>::read_npy(open()?)
                .map_err(bad)?
                .mapv(|v| v as f32 * scale),
            Err(e) => return Err(bad(e)),
        },
        Err(e) => return Err(bad(e)),
    };
    let (h, w) = values.dim();
    Ok((h, w, values.iter().copied().collect()))
}

/// A depth image: only 16-bit grey holds depth; an 8-bit one would be
/// rescaled by 257 without a word.
fn read_depth_png(path: &Path, scale: f32) -> Result<(usize, usize, Vec<f32>)> {
    input(path, MAX_IMAGE_BYTES)?;
    let img = image::open(path).with_context(|| format!("reading {}", path.display()))?;
    let image::DynamicImage::ImageLuma16(di) = img else {
        return Err(usage(format!(
            "{}: depth images must be 16-bit greyscale (units of --depth-scale metres), this one is {:?}",
            path.display(),
            img.color()
        )));
    };
    Ok((
        di.height() as usize,
        di.width() as usize,
        di.pixels().map(|p| p.0[0] as f32 * scale).collect(),
    ))
}

/// Where a robot's RGB-D camera sees a tabletop object: a median depth
/// outside this range (metres) usually means a wrong --depth-scale.
const PLAUSIBLE_DEPTH_M: std::ops::RangeInclusive<f32> = 0.05..=10.0;

/// A warning when the median valid depth lies outside [`PLAUSIBLE_DEPTH_M`],
/// with the scale that would bring it to about a metre.
fn implausible_depth(depth_m: &[f32], scale: f32, file: &Path) -> Option<String> {
    let mut valid: Vec<f32> = depth_m
        .iter()
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if valid.is_empty() {
        return None;
    }
    let mid = valid.len() / 2;
    let (_, median, _) = valid.select_nth_unstable_by(mid, f32::total_cmp);
    let median = *median;
    if PLAUSIBLE_DEPTH_M.contains(&median) {
        return None;
    }
    // The power of ten that puts the median between 0.3 and 3 m.
    let suggested = scale * 10f32.powf((1.0 / median).log10().round());
    Some(format!(
        "{}: the median depth is {median:.3e} m, outside the {:.2}..{:.0} m a camera sees \
         an object at; is the unit right? 16-bit depth is multiplied by --depth-scale \
         (now {scale}; {suggested:e} would put it at {:.2} m; millimetres are 0.001), and \
         float .npy depth is read as metres",
        file.display(),
        PLAUSIBLE_DEPTH_M.start(),
        PLAUSIBLE_DEPTH_M.end(),
        median * suggested / scale
    ))
}

/// Farthest depth (m) a frame may hold. 16-bit millimetres read as metres
/// (up to 65,535 m) stay below it, so the unit warning can name the fix;
/// past it the observation's coordinates are no longer a scene.
const MAX_DEPTH_M: f32 = 1e5;

/// Depth in metres as the policy will read it: 0 or a non-finite value means
/// "no return" (what depth cameras write there); a negative value or one
/// past [`MAX_DEPTH_M`] is an error naming the file and the pixel, and so is
/// a frame with no depth at all.
fn check_depth_values(depth_m: &[f32], width: usize, file: &Path) -> Result<()> {
    let width = width.max(1);
    if let Some((i, v)) = depth_m
        .iter()
        .enumerate()
        .find(|(_, v)| v.is_finite() && !(0.0..=MAX_DEPTH_M).contains(*v))
    {
        return Err(usage(format!(
            "{}: depth {v:e} m at pixel ({}, {}) (row, col); depth must be 0 (no return) or up to {MAX_DEPTH_M} m — check --depth-scale",
            file.display(),
            i / width,
            i % width
        )));
    }
    if !depth_m.iter().any(|v| v.is_finite() && *v > 0.0) {
        return Err(usage(format!(
            "{}: no pixel has a depth (every value is 0 or not a number); the policy needs the object's surface in view",
            file.display()
        )));
    }
    Ok(())
}

pub(super) fn load_frame(
    rgb: &Path,
    depth: &Path,
    a: &InferArgs,
    camera: &Camera,
) -> Result<OwnedFrame> {
    input(rgb, MAX_IMAGE_BYTES)?;
    let img = image::open(rgb)
        .with_context(|| format!("reading {}", rgb.display()))?
        .to_rgb8();
    let (h, w, d) = if depth.extension().is_some_and(|e| e == "npy") {
        read_npy(depth, a.depth_scale)?
    } else {
        read_depth_png(depth, a.depth_scale)?
    };
    if (h, w) != (img.height() as usize, img.width() as usize) {
        return Err(usage(format!(
            "{} is {}x{} but {} is {h}x{w}",
            rgb.display(),
            img.height(),
            img.width(),
            depth.display()
        )));
    }
    check_depth_values(&d, w, depth)?;
    if let Some(warning) = implausible_depth(&d, a.depth_scale, depth) {
        eprintln!("warning: {warning}");
    }
    Ok(OwnedFrame {
        width: w,
        height: h,
        rgb: img.into_raw(),
        depth: d,
        intrinsics: camera.intrinsics,
        world_from_camera: camera.world_from_camera,
    })
}

/// The checked camera flags.
pub(super) struct Camera {
    pub(super) intrinsics: [f32; 4],
    pub(super) world_from_camera: [[f32; 4]; 4],
    /// The image size a camera.json was written for, when it says.
    pub(super) size: Option<(usize, usize)>,
    /// Where the camera came from, for messages.
    pub(super) source: String,
}

/// Largest focal length or principal-point coordinate (pixels): a camera
/// with more is a unit mistake, not a lens.
const MAX_INTRINSIC_PX: f32 = 1e6;

#[derive(serde::Deserialize)]
struct CameraFile {
    intrinsics: FileIntrinsics,
    /// Rows of the 4x4 transform.
    world_from_camera: [[f32; 4]; 4],
    height: Option<usize>,
    width: Option<usize>,
}

#[derive(serde::Deserialize)]
struct FileIntrinsics {
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
}

impl Camera {
    pub(super) fn from_args(a: &InferArgs) -> Result<Camera> {
        let (intrinsics, pose, size, source) = match &a.camera {
            Some(path) => {
                let text =
                    umpnet_sim::fsio::read_text(path, 1 << 20).map_err(|e| usage(e.to_string()))?;
                let f: CameraFile = serde_json::from_str(&text).map_err(|e| {
                    usage(format!(
                        "{}: {e}; expected {{\"intrinsics\": {{\"fx\", \"fy\", \"cx\", \"cy\"}}, \"world_from_camera\": [4 rows of 4]}} as umpnet render writes",
                        path.display()
                    ))
                })?;
                let k = f.intrinsics;
                (
                    vec![k.fx, k.fy, k.cx, k.cy],
                    f.world_from_camera.iter().flatten().copied().collect(),
                    f.height.zip(f.width),
                    path.display().to_string(),
                )
            }
            None => (
                a.intrinsics.clone(),
                a.camera_pose.clone(),
                None,
                "--intrinsics/--camera-pose".to_owned(),
            ),
        };
        let (Ok(intrinsics), Ok(pose)) = (
            <[f32; 4]>::try_from(intrinsics.as_slice()),
            <[f32; 16]>::try_from(pose.as_slice()),
        ) else {
            return Err(usage(
                "--intrinsics takes fx,fy,cx,cy and --camera-pose 16 numbers (or give --camera camera.json)",
            ));
        };
        let [fx, fy, cx, cy] = intrinsics;
        let focal = |f: f32| f.is_finite() && f > 0.0 && f <= MAX_INTRINSIC_PX;
        let centre = |c: f32| c.is_finite() && c.abs() <= MAX_INTRINSIC_PX;
        if !(focal(fx) && focal(fy) && centre(cx) && centre(cy)) {
            return Err(usage(format!(
                "{source}: intrinsics {intrinsics:?}: fx and fy must be in (0, {MAX_INTRINSIC_PX:e}] pixels and cx, cy within ±{MAX_INTRINSIC_PX:e}"
            )));
        }
        let m = nalgebra::Matrix4::from_row_slice(&pose);
        let r = m.fixed_view::<3, 3>(0, 0);
        let rigid = pose.iter().all(|v| v.is_finite())
            && (r.transpose() * r - nalgebra::Matrix3::identity())
                .abs()
                .max()
                < 1e-3
            && (r.determinant() - 1.0).abs() < 1e-3
            && m.fixed_view::<1, 4>(3, 0) == nalgebra::RowVector4::new(0.0, 0.0, 0.0, 1.0);
        if !rigid {
            return Err(usage(format!(
                "{source}: camera pose {pose:?} is not a rigid transform: expected a rotation (orthonormal, determinant 1), a translation, and a last row of 0,0,0,1"
            )));
        }
        let limit = umpnet_sim::urdf::MAX_COORDINATE;
        if m.fixed_view::<3, 1>(0, 3).iter().any(|t| t.abs() > limit) {
            return Err(usage(format!(
                "{source}: the camera's translation {:?} is more than {limit} m from the origin",
                [pose[3], pose[7], pose[11]]
            )));
        }
        let mut world_from_camera = [[0.0f32; 4]; 4];
        for (row, values) in world_from_camera.iter_mut().zip(pose.chunks_exact(4)) {
            row.copy_from_slice(values);
        }
        Ok(Camera {
            intrinsics,
            world_from_camera,
            size,
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A version-1 .npy file of `h` x `w` little-endian float32 values.
    fn npy(h: usize, w: usize, descr: &str) -> Vec<u8> {
        let mut header =
            format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({h}, {w}), }}");
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend((header.len() as u16).to_le_bytes());
        out.extend(header.as_bytes());
        out.extend((0..h * w).flat_map(|i| (1.0 + i as f32).to_le_bytes()));
        out
    }

    /// Headers that lie (about the shape, the dtype, the header's own
    /// length, the version) are refused or read as what the file holds:
    /// nothing is allocated beyond the file's size, and nothing panics.
    #[test]
    fn mutated_npy_headers_are_refused_or_read_within_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("depth.npy");
        let shapes = [
            "0",
            "1",
            "4",
            "5",
            "20",
            "-1",
            "2147483648",
            "18446744073709551615",
            "99999999999999999999",
            "",
        ];
        let descrs = ["<f4", "<f8", "<u2", ">f4", "|b1", "<c16", "<f4f8"];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut read, mut refused) = (0, 0);
        for case in 0..2000 {
            let mut bytes = npy(4, 5, descrs[rng.random_range(0..descrs.len())]);
            let text = String::from_utf8_lossy(&bytes).into_owned();
            if case % 2 == 0 {
                let lie = format!(
                    "({}, {})",
                    shapes[rng.random_range(0..shapes.len())],
                    shapes[rng.random_range(0..shapes.len())]
                );
                let at = text.find("(4, 5)").unwrap();
                let mut b = bytes[..at].to_vec();
                b.extend(lie.as_bytes());
                b.extend(&bytes[at + 6..]);
                bytes = b;
            }
            match rng.random_range(0..4) {
                0 => bytes[6] = rng.random_range(0..5),
                1 => {
                    let k = rng.random_range(8..10);
                    bytes[k] = rng.random();
                }
                2 => bytes.truncate(rng.random_range(0..bytes.len())),
                _ => {}
            }
            std::fs::write(&path, &bytes).unwrap();
            match read_npy(&path, 0.001) {
                Ok((h, w, values)) => {
                    read += 1;
                    assert_eq!(values.len(), h * w);
                    assert!(
                        h * w * 2 <= bytes.len(),
                        "{h}x{w} from {} bytes",
                        bytes.len()
                    );
                }
                Err(e) => {
                    refused += 1;
                    let msg = format!("{e:#}");
                    assert!(msg.contains("depth.npy") && msg.len() < 2000, "{msg}");
                }
            }
        }
        assert!(read > 50 && refused > 500, "{read} read, {refused} refused");
    }
}
