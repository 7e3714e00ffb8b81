//! What an encoder input file is (Annex A.8.1): a model file (Annex A), a standard 3DGS PLY
//! (this profile), or one of the compressed splat formats people hand to it by mistake, which
//! get a message saying what they are and how to convert them.

use crate::error::{Error, Result};

/// The kinds of file `salvq encode` tells apart by their first bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// A safetensors model file (Annex A): the anchors profile.
    Model,
    /// A PLY file with a `vertex` element: the explicit profile.
    Ply,
}

const CONVERT: &str = "convert it to a standard 3DGS PLY first, e.g. \
`npx @playcanvas/splat-transform INPUT scene.ply`, then encode scene.ply";

/// How to turn an ASCII PLY into the binary one the encoder reads.
const ASCII_PLY: &str = "write it as binary little-endian first, e.g. with Python's plyfile \
(`pip install plyfile`): `python3 -c \"import plyfile; d = plyfile.PlyData.read('in.ply'); \
d.text = False; d.byte_order = '<'; d.write('scene.ply')\"`, then encode scene.ply";

/// Whether `bytes` start as a safetensors file does: an 8-byte little-endian header length
/// that fits the file, then the header's JSON object.
fn looks_like_safetensors(bytes: &[u8]) -> bool {
    match bytes {
        [a, b, c, d, e, f, g, h, b'{', ..] => {
            let n = u64::from_le_bytes([*a, *b, *c, *d, *e, *f, *g, *h]);
            n >= 2 && n <= bytes.len() as u64 - 8
        }
        _ => false,
    }
}

/// What `bytes` look like, for a message about a file the encoder does not read.
pub fn describe(bytes: &[u8]) -> String {
    let head = &bytes[..bytes.len().min(64)];
    if bytes.is_empty() {
        return "an empty file".into();
    }
    let text = std::str::from_utf8(head).ok().filter(|t| {
        t.chars()
            .all(|c| !c.is_control() || c.is_ascii_whitespace())
    });
    match text {
        Some(t) => {
            let line = t.lines().next().unwrap_or("").trim();
            let shown: String = line.chars().take(40).collect();
            format!("a text file (its first line: \"{shown}\")")
        }
        None => {
            let hex: Vec<String> = head.iter().take(8).map(|b| format!("{b:02x}")).collect();
            format!(
                "binary data of no kind salvq knows (first bytes {})",
                hex.join(" ")
            )
        }
    }
}

/// Classifies `bytes` (Annex A.8.1).
pub fn input_kind(bytes: &[u8]) -> Result<InputKind> {
    let unsupported = |found: &'static str| {
        Err(Error::UnsupportedInput {
            found: found.into(),
            hint: CONVERT,
        })
    };
    match bytes {
        [b'p', b'l', b'y', b'\n' | b'\r', ..] => {
            // PlayCanvas' compressed PLY declares a `chunk` element before its vertices.
            let head = &bytes[..bytes.len().min(4096)];
            let text = String::from_utf8_lossy(head);
            let mut lines = text.lines().map(str::trim_start);
            if lines.clone().any(|l| l.starts_with("element chunk")) {
                return unsupported("a PlayCanvas compressed PLY (element chunk)");
            }
            if lines.any(|l| l.starts_with("format ascii")) {
                return Err(Error::UnsupportedInput {
                    found: "an ASCII PLY (format ascii 1.0)".into(),
                    hint: ASCII_PLY,
                });
            }
            Ok(InputKind::Ply)
        }
        [0x1f, 0x8b, ..] => unsupported("a gzip file (an SPZ scene is gzip-compressed)"),
        [b'N', b'G', b'S', b'P', ..] => unsupported("an SPZ scene"),
        [b'P', b'K', 3, 4, ..] => unsupported("a zip archive (a bundled SOG scene is one)"),
        [b'{', ..] => unsupported("a JSON file (an unbundled SOG scene's meta.json is one)"),
        [b'R', b'I', b'F', b'F', _, _, _, _, b'W', b'E', b'B', b'P', ..] => {
            unsupported("a WebP image (part of an unbundled SOG scene)")
        }
        [0x89, b'S', b'A', b'L', b'V', b'Q', ..] => Err(Error::UnsupportedInput {
            found: "a SALVQ stream".into(),
            hint: "it is already encoded: `salvq extract` selects a rate, `salvq decode` \
                   decodes it",
        }),
        _ if looks_like_safetensors(bytes) => Ok(InputKind::Model),
        _ => Err(Error::UnsupportedInput {
            found: describe(bytes).into(),
            hint: "salvq encode reads a 3DGS scene as a binary PLY (the Inria layout: x, y, z, \
                   f_dc_*, opacity, scale_*, rot_*) or an anchor model as safetensors (spec \
                   Annex A)",
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn found(bytes: &[u8]) -> String {
        match input_kind(bytes) {
            Err(Error::UnsupportedInput { found, .. }) => found.into_owned(),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn inputs_are_named_by_what_their_bytes_look_like() {
        assert_eq!(found(b""), "an empty file");
        assert_eq!(
            found(b"hello world\nsecond line"),
            "a text file (its first line: \"hello world\")"
        );
        assert!(found(&[0, 1, 2, 250, 251, 7, 9, 0, 1]).starts_with("binary data"));
        assert_eq!(
            found(b"ply\nformat ascii 1.0\nelement vertex 1\n"),
            "an ASCII PLY (format ascii 1.0)"
        );
        let mut st = 2u64.to_le_bytes().to_vec();
        st.extend_from_slice(b"{}");
        assert_eq!(input_kind(&st).unwrap(), InputKind::Model);
        let mut too_long = 900u64.to_le_bytes().to_vec();
        too_long.extend_from_slice(b"{}");
        assert!(found(&too_long).starts_with("binary data"));
        assert_eq!(
            input_kind(b"ply\nformat binary_little_endian 1.0\n").unwrap(),
            InputKind::Ply
        );
    }
}
