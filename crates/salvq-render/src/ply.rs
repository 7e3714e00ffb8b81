//! The Inria 3DGS PLY file (spec Annex C.3): the layout that the reference 3DGS code
//! (`scene/gaussian_model.py`, `save_ply` / `load_ply`) writes and common viewers read.
//!
//! Written: one `vertex` element, every property `float` (binary32), binary little-endian,
//!
//! ```text
//! x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 f_rest_0 … f_rest_{3B−1} opacity scale_0..2 rot_0..3
//! ```
//!
//! with `f_rest` channel-major (`f_rest_{c·B + k}`), `opacity` a logit, `scale_*` natural
//! log-scales, `rot_0` the quaternion's w, and the normals zero.
//!
//! Read: any PLY whose `vertex` element has those properties, found by name in any order
//! (others ignored), of any fixed-size scalar type, in either binary byte order; elements
//! before `vertex` are skipped by their record size. The reader never panics and never
//! allocates from a count before checking `count × stride` against the file's length. Values
//! must be finite, except `opacity`, which may be ±∞ (alpha 0 or 1).
//!
//! A PLY file that `salvq export-ply` writes from a scene model also records, in a header
//! comment ([`RING_BOUNDS_COMMENT`]), the bounds its camera ring is placed around (the
//! anchors', Annex C.2 step 1), so that view I of the PLY is view I of the model it came from.

use std::io::Write;

use super::camera::Bounds;
use super::{rest_per_channel, Gaussians};
use crate::error::{Error, Result};

/// Largest header the reader scans for `end_header` (a 3DGS header with SH degree 3 is
/// about 1.3 KB).
pub const MAX_HEADER_BYTES: usize = 1 << 16;

/// A fixed-size PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The value at the start of `b` (at least `size()` bytes) as binary32.
    fn read(self, b: &[u8], little: bool) -> f32 {
        fn arr<const N: usize>(b: &[u8], little: bool) -> [u8; N] {
            let mut a = [0u8; N];
            a.copy_from_slice(&b[..N]);
            if !little {
                a.reverse();
            }
            a
        }
        match self {
            Scalar::I8 => f32::from(b[0] as i8),
            Scalar::U8 => f32::from(b[0]),
            Scalar::I16 => f32::from(i16::from_le_bytes(arr(b, little))),
            Scalar::U16 => f32::from(u16::from_le_bytes(arr(b, little))),
            Scalar::I32 => i32::from_le_bytes(arr(b, little)) as f32,
            Scalar::U32 => u32::from_le_bytes(arr(b, little)) as f32,
            Scalar::F32 => f32::from_le_bytes(arr(b, little)),
            Scalar::F64 => f64::from_le_bytes(arr(b, little)) as f32,
        }
    }
}

/// One element of the header: name, count, and its properties (`None`: a list property,
/// whose records have no fixed size).
struct Element {
    name: String,
    count: u64,
    properties: Vec<(String, Option<Scalar>)>,
}

impl Element {
    /// Record size in bytes, `None` with a list property.
    fn stride(&self) -> Option<u64> {
        self.properties
            .iter()
            .try_fold(0u64, |a, (_, t)| t.map(|t| a + t.size() as u64))
    }
}

/// The parsed header: byte order, elements, the recorded ring bounds, and where the body
/// starts.
struct Header {
    little_endian: bool,
    elements: Vec<Element>,
    ring_bounds: Option<Bounds>,
    body_start: usize,
}

/// The header comment's keywords that record the camera ring's bounds (Annex C.3):
/// `comment salvq ring_bounds xmin ymin zmin xmax ymax zmax`, six binary32 values written
/// in their shortest decimal form, so that they read back exactly.
pub const RING_BOUNDS_COMMENT: &str = "salvq ring_bounds";

/// The six numbers of a ring-bounds comment: finite, each min ≤ its max.
fn parse_ring_bounds(values: &[&str], line: usize) -> Result<Bounds> {
    let invalid = || {
        header_error(
            line,
            "'comment salvq ring_bounds' takes 6 finite numbers, min <= max on each axis",
        )
    };
    let v: Vec<f32> = values
        .iter()
        .map(|x| x.parse::<f32>().map_err(|_| invalid()))
        .collect::<Result<_>>()?;
    let [x0, y0, z0, x1, y1, z1]: [f32; 6] = v.try_into().map_err(|_| invalid())?;
    let (min, max) = ([x0, y0, z0], [x1, y1, z1]);
    if (0..3).any(|a| !(min[a].is_finite() && max[a].is_finite() && min[a] <= max[a])) {
        return Err(invalid());
    }
    Ok(Bounds { min, max })
}

fn header_error(line: usize, rule: &'static str) -> Error {
    Error::PlyHeaderInvalid {
        line: u32::try_from(line).unwrap_or(u32::MAX),
        rule,
    }
}

fn parse_header(bytes: &[u8]) -> Result<Header> {
    let scan = &bytes[..bytes.len().min(MAX_HEADER_BYTES)];
    let end = find(scan, b"\nend_header")
        .map(|p| p + 1)
        .ok_or_else(|| header_error(0, "no 'end_header' line within the first 65536 bytes"))?;
    // The body starts after the newline that ends `end_header` (`\n` or `\r\n`).
    let after = end + b"end_header".len();
    let body_start = match bytes.get(after..) {
        Some([b'\n', ..]) => after + 1,
        Some([b'\r', b'\n', ..]) => after + 2,
        _ => return Err(header_error(0, "'end_header' must end its line")),
    };
    let text = std::str::from_utf8(&bytes[..after])
        .map_err(|_| header_error(0, "the header is not ASCII text"))?;
    let mut lines = text.lines().map(|l| l.trim_end_matches('\r'));
    if lines.next() != Some("ply") {
        return Err(header_error(1, "a PLY file starts with the line 'ply'"));
    }
    let mut little_endian = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut ring_bounds = None;
    for (i, line) in lines.enumerate() {
        let number = i + 2;
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        match words.as_slice() {
            ["format", "binary_little_endian", "1.0"] => little_endian = Some(true),
            ["format", "binary_big_endian", "1.0"] => little_endian = Some(false),
            ["format", "ascii", ..] => {
                return Err(header_error(number, "ASCII PLY is not supported"))
            }
            ["format", ..] => {
                return Err(header_error(
                    number,
                    "format must be binary_little_endian or binary_big_endian 1.0",
                ))
            }
            ["comment", "salvq", "ring_bounds", values @ ..] => {
                ring_bounds = Some(parse_ring_bounds(values, number)?);
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => {
                let count = count.parse::<u64>().map_err(|_| {
                    header_error(number, "an element count is a non-negative integer")
                })?;
                elements.push(Element {
                    name: (*name).to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", _, _, name] => {
                let e = elements.last_mut().ok_or_else(|| {
                    header_error(number, "a property must follow an element line")
                })?;
                e.properties.push(((*name).to_string(), None));
            }
            ["property", kind, name] => {
                let scalar = Scalar::parse(kind)
                    .ok_or_else(|| header_error(number, "unknown property type"))?;
                let e = elements.last_mut().ok_or_else(|| {
                    header_error(number, "a property must follow an element line")
                })?;
                if e.properties.iter().any(|(n, _)| n == name) {
                    return Err(header_error(number, "a property name appears twice"));
                }
                e.properties.push(((*name).to_string(), Some(scalar)));
            }
            ["end_header"] => break,
            _ => return Err(header_error(number, "not a PLY header line")),
        }
    }
    let little_endian =
        little_endian.ok_or_else(|| header_error(0, "the header has no 'format' line"))?;
    Ok(Header {
        little_endian,
        elements,
        ring_bounds,
        body_start,
    })
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// The properties a Gaussian needs besides `f_rest_*`, in [`Gaussians`] field order.
const REQUIRED: [&str; 14] = [
    "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
    "rot_0", "rot_1", "rot_2", "rot_3",
];

/// Reads the Gaussians of a 3DGS PLY file (Annex C.3).
pub fn read_ply(bytes: &[u8]) -> Result<Gaussians> {
    read_ply_with(bytes, true)
}

/// [`read_ply`] that keeps NaN and infinite values (an encoder that drops such Gaussians,
/// Annex A.8.1, reads with it).
pub fn read_ply_lenient(bytes: &[u8]) -> Result<Gaussians> {
    read_ply_with(bytes, false)
}

/// The ring bounds a PLY file's header records ([`RING_BOUNDS_COMMENT`]), if any: the
/// camera ring of a PLY exported from a scene model is placed around them (Annex C.2 step 1).
pub fn recorded_ring_bounds(bytes: &[u8]) -> Result<Option<Bounds>> {
    Ok(parse_header(bytes)?.ring_bounds)
}

/// The vertex properties of a PLY file that a Gaussian does not use (not the Annex C.3
/// ones, the normals or `f_rest_*`): what a reader ignores. Empty if the header does not
/// parse.
pub fn unused_properties(bytes: &[u8]) -> Vec<String> {
    let Ok(header) = parse_header(bytes) else {
        return Vec::new();
    };
    header
        .elements
        .iter()
        .filter(|e| e.name == "vertex")
        .flat_map(|e| e.properties.iter().map(|p| p.0.clone()))
        .filter(|n| {
            !REQUIRED.contains(&n.as_str())
                && !n.starts_with("f_rest_")
                && !["nx", "ny", "nz"].contains(&n.as_str())
        })
        .collect()
}

/// [`read_ply`] (`strict`) or [`read_ply_lenient`]: the vertex element located, its
/// properties found by name, then every record read (Annex C.3).
fn read_ply_with(bytes: &[u8], strict: bool) -> Result<Gaussians> {
    let header = parse_header(bytes)?;
    let body = &bytes[header.body_start..];
    let (element, offset, stride) = locate_vertex(&header, body)?;
    let data = &body[offset as usize..][..(element.count * stride) as usize];
    let VertexColumns {
        required,
        rest,
        sh_degree,
    } = vertex_columns(element)?;
    let rest_count = rest.len();
    let n = element.count as usize;
    let little = header.little_endian;
    let mut g = Gaussians {
        positions: Vec::with_capacity(n),
        sh_degree,
        f_dc: Vec::with_capacity(n),
        f_rest: Vec::with_capacity(n * rest_count),
        opacity_logit: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
    };
    let mut values = [0f32; REQUIRED.len()];
    for (v, record) in data.chunks_exact(stride as usize).enumerate() {
        let read = |c: Column<'_>| -> Result<f32> {
            let x = c.2.read(&record[c.1..], little);
            // An infinite opacity logit is an alpha of exactly 0 or 1, which tools that
            // store 8-bit alphas write (splat-transform); the renderer's sigmoid takes it.
            if !strict || x.is_finite() || (c.0 == "opacity" && x.is_infinite()) {
                Ok(x)
            } else {
                Err(Error::PlyValueNotFinite {
                    vertex: v as u64,
                    property: c.0.to_string(),
                })
            }
        };
        for (slot, &c) in values.iter_mut().zip(&required) {
            *slot = read(c)?;
        }
        let [x, y, z, d0, d1, d2, o, s0, s1, s2, r0, r1, r2, r3] = values;
        g.positions.push([x, y, z]);
        g.f_dc.push([d0, d1, d2]);
        g.opacity_logit.push(o);
        g.log_scales.push([s0, s1, s2]);
        g.rotations.push([r0, r1, r2, r3]);
        for &c in &rest {
            g.f_rest.push(read(c)?);
        }
    }
    Ok(g)
}

/// A property's name, byte offset in the record, and type.
type Column<'a> = (&'a str, usize, Scalar);

/// The `vertex` element of `header`, its byte offset in `body`, and its record size: the
/// elements before it are skipped, each of a fixed record size and all within the file.
fn locate_vertex<'h>(header: &'h Header, body: &[u8]) -> Result<(&'h Element, u64, u64)> {
    let mut offset = 0u64;
    for e in &header.elements {
        let stride = e.stride().ok_or_else(|| {
            header_error(
                0,
                "list properties are not supported in or before the vertex element",
            )
        })?;
        let needed = e.count.checked_mul(stride);
        let available = (body.len() as u64).saturating_sub(offset);
        if needed.is_none_or(|n| n > available) {
            return Err(Error::PlyTruncated {
                element: e.name.clone(),
                count: e.count,
                stride,
                available,
            });
        }
        if e.name == "vertex" {
            return Ok((e, offset, stride));
        }
        offset += needed.unwrap_or(0);
    }
    Err(header_error(0, "the file has no 'vertex' element"))
}

/// The vertex properties a Gaussian reads, found by name.
struct VertexColumns<'a> {
    /// The [`REQUIRED`] properties, in that order.
    required: Vec<Column<'a>>,
    /// `f_rest_0` … `f_rest_{3B−1}`, in that order.
    rest: Vec<Column<'a>>,
    /// The SH degree their count gives.
    sh_degree: u8,
}

/// Finds the [`REQUIRED`] properties and the `f_rest_*` ones of the vertex element `element`
/// (whose every property has a fixed type, checked by `stride()`); their count gives the SH
/// degree (Annex C.3).
fn vertex_columns(element: &Element) -> Result<VertexColumns<'_>> {
    let mut columns = Vec::with_capacity(element.properties.len());
    let mut at = 0usize;
    for (name, t) in &element.properties {
        let t = t.unwrap_or(Scalar::U8); // every type is fixed here (checked by stride())
        columns.push((name.as_str(), at, t));
        at += t.size();
    }
    let column = |name: &str| columns.iter().find(|c| c.0 == name).copied();
    let mut required = Vec::with_capacity(REQUIRED.len());
    for name in REQUIRED {
        required.push(column(name).ok_or(Error::PlyPropertyMissing { property: name })?);
    }
    let rest_count = columns
        .iter()
        .filter(|c| c.0.starts_with("f_rest_"))
        .count();
    let sh_degree = match rest_count {
        0 => 0u8,
        9 => 1,
        24 => 2,
        45 => 3,
        n => {
            return Err(Error::PlyShCoefficients {
                count: u32::try_from(n).unwrap_or(u32::MAX),
            })
        }
    };
    let mut rest = Vec::with_capacity(rest_count);
    for i in 0..rest_count {
        rest.push(
            column(&format!("f_rest_{i}")).ok_or(Error::PlyShCoefficients {
                count: rest_count as u32,
            })?,
        );
    }
    Ok(VertexColumns {
        required,
        rest,
        sh_degree,
    })
}

/// The header of the PLY file [`write_ply`] writes for `n` Gaussians of SH degree `degree`.
pub fn ply_header(n: usize, degree: u8) -> String {
    let mut h = format!("ply\nformat binary_little_endian 1.0\nelement vertex {n}\n");
    let mut names: Vec<String> = [
        "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2",
    ]
    .map(String::from)
    .to_vec();
    names.extend((0..3 * rest_per_channel(degree)).map(|i| format!("f_rest_{i}")));
    names.extend(
        [
            "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
        ]
        .map(String::from),
    );
    for name in names {
        h.push_str("property float ");
        h.push_str(&name);
        h.push('\n');
    }
    h.push_str("end_header\n");
    h
}

/// Writes the Gaussians in the Inria 3DGS PLY layout (Annex C.3). Fails only if `w` does, or
/// with `InvalidInput` when the per-Gaussian vectors disagree in length.
pub fn write_ply(g: &Gaussians, w: &mut dyn Write) -> std::io::Result<()> {
    write_ply_with(g, None, w)
}

/// [`write_ply`], with the bounds the file's camera ring is placed around recorded in the
/// header ([`RING_BOUNDS_COMMENT`]) when given and finite.
pub fn write_ply_with(
    g: &Gaussians,
    ring_bounds: Option<&Bounds>,
    w: &mut dyn Write,
) -> std::io::Result<()> {
    let n = g.len();
    let b = g.rest_per_channel();
    let consistent = g.sh_degree <= 3
        && [
            g.f_dc.len(),
            g.opacity_logit.len(),
            g.log_scales.len(),
            g.rotations.len(),
        ]
        .iter()
        .all(|&l| l == n)
        && g.f_rest.len() == n * 3 * b;
    if !consistent {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "Gaussians: per-Gaussian vectors of different lengths",
        ));
    }
    let mut header = ply_header(n, g.sh_degree);
    let finite = |b: &&Bounds| b.min.iter().chain(&b.max).all(|v| v.is_finite());
    if let Some(b) = ring_bounds.filter(finite) {
        let [x0, y0, z0] = b.min;
        let [x1, y1, z1] = b.max;
        // After the format line (line 3), where readers expect comments.
        let at = header.find("element").unwrap_or(0);
        header.insert_str(
            at,
            &format!("comment {RING_BOUNDS_COMMENT} {x0} {y0} {z0} {x1} {y1} {z1}\n"),
        );
    }
    w.write_all(header.as_bytes())?;
    let mut record = Vec::with_capacity(4 * (17 + 3 * b));
    for i in 0..n {
        record.clear();
        let rest = &g.f_rest[i * 3 * b..(i + 1) * 3 * b];
        let values = g.positions[i]
            .iter()
            .chain(&[0.0; 3])
            .chain(&g.f_dc[i])
            .chain(rest)
            .chain(std::iter::once(&g.opacity_logit[i]))
            .chain(&g.log_scales[i])
            .chain(&g.rotations[i]);
        for v in values {
            record.extend_from_slice(&v.to_le_bytes());
        }
        w.write_all(&record)?;
    }
    Ok(())
}

/// The PLY file's bytes (see [`write_ply`]).
pub fn ply_bytes(g: &Gaussians) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    write_ply(g, &mut out)?;
    Ok(out)
}

/// Writes a PLY file atomically (spec §9.2).
pub fn write_ply_file(g: &Gaussians, path: &std::path::Path) -> Result<()> {
    write_ply_file_with(g, None, path)
}

/// [`write_ply_file`] with [`write_ply_with`]'s ring bounds.
pub fn write_ply_file_with(
    g: &Gaussians,
    ring_bounds: Option<&Bounds>,
    path: &std::path::Path,
) -> Result<()> {
    crate::io::write_atomic(path, |w| write_ply_with(g, ring_bounds, w))
}
