//! Cameras of real captures (Annex C.2): the Inria 3DGS `cameras.json` and COLMAP's text
//! model (`cameras.txt`, `images.txt`), read into [`Camera`]s.
//!
//! Both describe the camera in the convention [`Camera`] uses (+x right, +y down, +z
//! forward), so the mapping is a change of representation only:
//!
//! - `cameras.json` (`camera_to_JSON` in `utils/camera_utils.py` of
//!   graphdeco-inria/gaussian-splatting) holds per camera `width`, `height`, `fx`, `fy`, the
//!   camera centre `position` and `rotation`, the **camera-to-world** rotation as a list of
//!   rows (its columns are the camera's right, down and forward axes in world space). The
//!   world-to-camera rotation is its transpose.
//! - COLMAP's `images.txt` holds per image `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME` and
//!   a second line of 2D points (ignored): the **world-to-camera** transform
//!   `x_cam = R(q) x_world + t`, so the rotation is `R(q)` and the centre `−R(q)ᵀ t`.
//!   `cameras.txt` holds per camera `CAMERA_ID MODEL WIDTH HEIGHT PARAMS…`.
//!
//! As 3DGS does, the renderer puts the principal point at the image centre: COLMAP's `cx cy`
//! are read and not used (3DGS trains and renders with a centred principal point, so that is
//! the camera its Gaussians were fitted to). COLMAP images are sorted by name, as 3DGS's
//! loader sorts them; `cameras.json` keeps its order.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use serde_json::value::RawValue;

use crate::camera::{Camera, MAX_IMAGE_SIDE};
use crate::error::{Error, Result};

/// A camera of a camera file and the image it was taken for.
#[derive(Debug, Clone, PartialEq)]
pub struct NamedCamera {
    /// The image's name (`img_name`, COLMAP's `NAME`; the entry index when there is none).
    pub name: String,
    /// The camera.
    pub camera: Camera,
}

/// Largest difference from the identity that `R Rᵀ` may show for `R` to count as a rotation:
/// the files print 6 to 17 significant digits.
const ROTATION_TOLERANCE: f64 = 1e-3;

/// Shortens what a file holds for an error message.
fn shown(value: &str) -> String {
    const MAX: usize = 60;
    match value.char_indices().nth(MAX) {
        Some((at, _)) => format!("{}…", &value[..at]),
        None => value.to_string(),
    }
}

/// Where each problem of one file is reported: the file, and in a `cameras.json` the
/// camera's index (3DGS writes the whole list on one line).
struct Reporter<'a> {
    path: &'a Path,
    entry: Option<usize>,
}

impl Reporter<'_> {
    fn error(&self, line: u64, field: &'static str, problem: impl Into<String>) -> Error {
        let problem = problem.into();
        Error::CameraFileInvalid {
            path: self.path.to_path_buf(),
            line,
            field,
            problem: match self.entry {
                Some(i) => format!("camera {i}: {problem}"),
                None => problem,
            },
        }
    }
}

fn read_text(path: &Path) -> Result<String> {
    let bytes = crate::io::read_file(path)?;
    String::from_utf8(bytes).map_err(|e| Error::CameraFileInvalid {
        path: path.to_path_buf(),
        line: 0,
        field: "text",
        problem: format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
    })
}

fn check_size(r: &Reporter, line: u64, field: &'static str, v: u64) -> Result<u32> {
    match u32::try_from(v) {
        Ok(side) if (1..=MAX_IMAGE_SIDE).contains(&side) => Ok(side),
        _ => Err(r.error(
            line,
            field,
            format!("{v}: image sides are 1 … {MAX_IMAGE_SIDE} pixels"),
        )),
    }
}

fn check_focal(r: &Reporter, line: u64, field: &'static str, v: f64) -> Result<f32> {
    let f = v as f32;
    if f.is_finite() && f > 0.0 {
        Ok(f)
    } else {
        Err(r.error(
            line,
            field,
            format!("{v}: a focal length is a positive finite number of pixels"),
        ))
    }
}

/// `true` when `m` is a rotation: rows orthonormal and determinant +1 (not a reflection).
fn is_rotation(m: &[[f64; 3]; 3]) -> bool {
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let orthonormal = (0..3).all(|i| {
        (0..3).all(|j| {
            let target = if i == j { 1.0 } else { 0.0 };
            (dot(&m[i], &m[j]) - target).abs() <= ROTATION_TOLERANCE
        })
    });
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    orthonormal && det > 0.0
}

fn transpose(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| m[j][i]))
}

fn to_f32<const N: usize>(v: [f64; N]) -> [f32; N] {
    v.map(|x| x as f32)
}

// ---------------------------------------------------------------------------------------
// Inria 3DGS cameras.json

/// Reads the Inria 3DGS `cameras.json` at `path`.
pub fn read_inria_json(path: &Path) -> Result<Vec<NamedCamera>> {
    parse_inria_json(&read_text(path)?, path)
}

/// The cameras of an Inria 3DGS `cameras.json` whose text is `text` (`path` names it in
/// errors): a JSON list of objects with `width`, `height`, `position` (3 numbers), `rotation`
/// (3 rows of 3: camera-to-world), `fx`, `fy`, and optionally `id` and `img_name`.
pub fn parse_inria_json(text: &str, path: &Path) -> Result<Vec<NamedCamera>> {
    let r = Reporter { path, entry: None };
    // Line of a value borrowed from `text` (its offset in it: the value lies inside `text`).
    let line_of = |raw: &RawValue| -> u64 {
        let offset = (raw.get().as_ptr() as usize).saturating_sub(text.as_ptr() as usize);
        let before = text.as_bytes().get(..offset).unwrap_or_default();
        1 + before.iter().filter(|&&b| b == b'\n').count() as u64
    };
    let syntax = |e: serde_json::Error, field| r.error(e.line() as u64, field, e.to_string());
    let entries: Vec<&RawValue> = serde_json::from_str(text).map_err(|e| syntax(e, "JSON"))?;
    if entries.is_empty() {
        return Err(r.error(0, "cameras", "the list holds no camera"));
    }
    let mut cameras = Vec::with_capacity(entries.len());
    for (index, entry) in entries.into_iter().enumerate() {
        let r = Reporter {
            path,
            entry: Some(index),
        };
        let entry_line = line_of(entry);
        let fields: BTreeMap<String, &RawValue> = serde_json::from_str(entry.get())
            .map_err(|e| r.error(entry_line, "camera", format!("not a JSON object ({e})")))?;
        let raw = |name: &'static str| {
            fields
                .get(name)
                .copied()
                .ok_or_else(|| r.error(entry_line, name, format!("no field '{name}'")))
        };
        fn value<T: serde::de::DeserializeOwned>(
            r: &Reporter,
            line: u64,
            name: &'static str,
            raw: &RawValue,
            expected: &str,
        ) -> Result<T> {
            serde_json::from_str(raw.get()).map_err(|_| {
                r.error(
                    line,
                    name,
                    format!("{}: expected {expected}", shown(raw.get())),
                )
            })
        }
        let field = |name: &'static str| -> Result<(u64, &RawValue)> {
            let v = raw(name)?;
            Ok((line_of(v), v))
        };
        let (l, v) = field("width")?;
        let width = check_size(&r, l, "width", value(&r, l, "width", v, "an integer")?)?;
        let (l, v) = field("height")?;
        let height = check_size(&r, l, "height", value(&r, l, "height", v, "an integer")?)?;
        let (l, v) = field("fx")?;
        let fx = check_focal(&r, l, "fx", value(&r, l, "fx", v, "a number")?)?;
        let (l, v) = field("fy")?;
        let fy = check_focal(&r, l, "fy", value(&r, l, "fy", v, "a number")?)?;
        let (l, v) = field("position")?;
        let position: [f64; 3] = value(&r, l, "position", v, "3 numbers")?;
        if !position.iter().all(|x| x.is_finite()) {
            return Err(r.error(l, "position", "the camera centre must be finite"));
        }
        let (l, v) = field("rotation")?;
        let camera_to_world: [[f64; 3]; 3] = value(&r, l, "rotation", v, "3 rows of 3 numbers")?;
        if !is_rotation(&camera_to_world) {
            return Err(r.error(
                l,
                "rotation",
                format!(
                    "{}: not a rotation matrix (orthonormal rows, determinant +1)",
                    shown(v.get())
                ),
            ));
        }
        let name = match fields
            .get("img_name")
            .map(|v| serde_json::from_str(v.get()))
        {
            Some(Ok(name)) => name,
            _ => match fields.get("id") {
                Some(id) => id.get().to_string(),
                None => index.to_string(),
            },
        };
        cameras.push(NamedCamera {
            name,
            camera: Camera {
                width,
                height,
                fx,
                fy,
                position: to_f32(position),
                // Camera-to-world rows, transposed: world-to-camera rows (right, down, forward).
                rotation: transpose(&camera_to_world).map(to_f32),
            },
        });
    }
    Ok(cameras)
}

// ---------------------------------------------------------------------------------------
// COLMAP text model

/// Intrinsics of one `cameras.txt` line that the renderer can draw.
struct Intrinsics {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
}

/// COLMAP's camera models: parameter count, and which parameters are the focal lengths
/// (`fx`, `fy`; the same one for a single focal length) and which are lens distortion.
/// `None` for the models that are not a pinhole even with zero distortion (fisheye, FOV).
fn model_layout(model: &str) -> Option<Option<(usize, [usize; 2], usize)>> {
    // (parameter count, focal indices, index of the first distortion parameter)
    Some(match model {
        "SIMPLE_PINHOLE" => Some((3, [0, 0], 3)),
        "PINHOLE" => Some((4, [0, 1], 4)),
        "SIMPLE_RADIAL" => Some((4, [0, 0], 3)),
        "RADIAL" => Some((5, [0, 0], 3)),
        "OPENCV" => Some((8, [0, 1], 4)),
        "FULL_OPENCV" => Some((12, [0, 1], 4)),
        "OPENCV_FISHEYE"
        | "FOV"
        | "SIMPLE_RADIAL_FISHEYE"
        | "RADIAL_FISHEYE"
        | "THIN_PRISM_FISHEYE" => None,
        _ => return None,
    })
}

/// Numbered lines that are neither blank nor `#` comments.
fn data_lines(text: &str) -> impl Iterator<Item = (u64, Vec<&str>)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i as u64 + 1, l.split_ascii_whitespace().collect::<Vec<_>>()))
        .filter(|(_, w)| w.first().is_some_and(|w| !w.starts_with('#')))
}

fn number<T: std::str::FromStr>(
    r: &Reporter,
    line: u64,
    field: &'static str,
    word: Option<&&str>,
) -> Result<T> {
    let word = word.ok_or_else(|| r.error(line, field, "missing"))?;
    word.parse::<T>()
        .map_err(|_| r.error(line, field, format!("'{}' is not a number", shown(word))))
}

/// The cameras of `cameras.txt`, by `CAMERA_ID`.
fn parse_cameras_txt(text: &str, path: &Path) -> Result<HashMap<u32, Intrinsics>> {
    let r = Reporter { path, entry: None };
    let mut cameras = HashMap::new();
    for (line, words) in data_lines(text) {
        let id: u32 = number(&r, line, "CAMERA_ID", words.first())?;
        let model = *words
            .get(1)
            .ok_or_else(|| r.error(line, "MODEL", "missing"))?;
        let layout = model_layout(model).ok_or_else(|| {
            r.error(
                line,
                "MODEL",
                format!("unknown COLMAP camera model '{}'", shown(model)),
            )
        })?;
        let (count, [ifx, ify], distortion) = layout.ok_or_else(|| {
            r.error(
                line,
                "MODEL",
                format!("{model} is not a pinhole camera; undistort the images first (colmap image_undistorter writes PINHOLE cameras)"),
            )
        })?;
        let width = check_size(&r, line, "WIDTH", number(&r, line, "WIDTH", words.get(2))?)?;
        let height = check_size(
            &r,
            line,
            "HEIGHT",
            number(&r, line, "HEIGHT", words.get(3))?,
        )?;
        let params = &words[4.min(words.len())..];
        if params.len() != count {
            return Err(r.error(
                line,
                "PARAMS",
                format!("{model} has {count} parameters, the line {}", params.len()),
            ));
        }
        let values = params
            .iter()
            .map(|p| number::<f64>(&r, line, "PARAMS", Some(p)))
            .collect::<Result<Vec<_>>>()?;
        if values[distortion..].iter().any(|&k| k != 0.0) {
            return Err(r.error(
                line,
                "PARAMS",
                format!(
                    "{model} with lens distortion {:?}: the renderer draws pinhole cameras; undistort the images first (colmap image_undistorter)",
                    &values[distortion..]
                ),
            ));
        }
        let focal = |field, i: usize| check_focal(&r, line, field, values[i]).map(f64::from);
        let intrinsics = Intrinsics {
            width,
            height,
            fx: focal("PARAMS (fx)", ifx)?,
            fy: focal("PARAMS (fy)", ify)?,
        };
        if cameras.insert(id, intrinsics).is_some() {
            return Err(r.error(line, "CAMERA_ID", format!("camera {id} appears twice")));
        }
    }
    Ok(cameras)
}

/// The cameras of a COLMAP text model: `cameras_txt` and `images_txt` are the two files'
/// text, `cameras_path` and `images_path` name them in errors. Sorted by image name.
pub fn parse_colmap(
    cameras_txt: &str,
    cameras_path: &Path,
    images_txt: &str,
    images_path: &Path,
) -> Result<Vec<NamedCamera>> {
    let intrinsics = parse_cameras_txt(cameras_txt, cameras_path)?;
    let r = Reporter {
        path: images_path,
        entry: None,
    };
    let mut cameras = Vec::new();
    let mut lines = images_txt.lines().enumerate();
    while let Some((i, text)) = lines.next() {
        let line = i as u64 + 1;
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        if words.first().is_none_or(|w| w.starts_with('#')) {
            continue;
        }
        // The image's 2D points follow on the next line, which may be empty.
        lines.next();
        let _id: u32 = number(&r, line, "IMAGE_ID", words.first())?;
        let mut q = [0f64; 4];
        for (k, field) in ["QW", "QX", "QY", "QZ"].into_iter().enumerate() {
            q[k] = number(&r, line, field, words.get(1 + k))?;
        }
        let mut t = [0f64; 3];
        for (k, field) in ["TX", "TY", "TZ"].into_iter().enumerate() {
            t[k] = number(&r, line, field, words.get(5 + k))?;
        }
        let camera_id: u32 = number(&r, line, "CAMERA_ID", words.get(8))?;
        let name = words
            .get(9..)
            .filter(|n| !n.is_empty())
            .map(|n| n.join(" "));
        let name = name.ok_or_else(|| r.error(line, "NAME", "missing"))?;
        let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 1e-6 && t.iter().all(|v| v.is_finite())) {
            return Err(r.error(
                line,
                "QW QX QY QZ TX TY TZ",
                "the pose needs a finite non-zero quaternion and a finite translation",
            ));
        }
        let k = intrinsics.get(&camera_id).ok_or_else(|| {
            r.error(
                line,
                "CAMERA_ID",
                format!("camera {camera_id} is not in {}", cameras_path.display()),
            )
        })?;
        let rotation = crate::camera::rotation_of(q.map(|v| v / norm));
        // x_cam = R x + t, so the centre, where x_cam = 0, is −Rᵀ t.
        let centre: [f64; 3] =
            std::array::from_fn(|a| -(0..3).map(|b| rotation[b][a] * t[b]).sum::<f64>());
        cameras.push(NamedCamera {
            name,
            camera: Camera {
                width: k.width,
                height: k.height,
                fx: k.fx as f32,
                fy: k.fy as f32,
                position: to_f32(centre),
                rotation: rotation.map(to_f32),
            },
        });
    }
    if cameras.is_empty() {
        return Err(r.error(0, "images", "no images"));
    }
    // 3DGS's loader sorts its cameras by image name; so do we, for the same view order.
    cameras.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(cameras)
}

/// Reads the COLMAP text model in `dir` (`cameras.txt` and `images.txt`, as in `sparse/0`
/// after `colmap model_converter --output_type TXT`).
pub fn read_colmap_dir(dir: &Path) -> Result<Vec<NamedCamera>> {
    let cameras_path: PathBuf = dir.join("cameras.txt");
    let images_path: PathBuf = dir.join("images.txt");
    if !cameras_path.exists() && dir.join("cameras.bin").exists() {
        return Err(Error::CameraFileInvalid {
            path: cameras_path,
            line: 0,
            field: "file",
            problem: "only the binary model is there; convert it with `colmap model_converter --input_path DIR --output_path DIR --output_type TXT`".into(),
        });
    }
    parse_colmap(
        &read_text(&cameras_path)?,
        &cameras_path,
        &read_text(&images_path)?,
        &images_path,
    )
}
