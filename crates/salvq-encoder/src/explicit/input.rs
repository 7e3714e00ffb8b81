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

/// Classifies `bytes` (Annex A.8.1).
pub fn input_kind(bytes: &[u8]) -> Result<InputKind> {
    let unsupported = |found: &'static str| {
        Err(Error::UnsupportedInput {
            found,
            hint: CONVERT,
        })
    };
    match bytes {
        [b'p', b'l', b'y', b'\n' | b'\r', ..] => {
            // PlayCanvas' compressed PLY declares a `chunk` element before its vertices.
            let head = &bytes[..bytes.len().min(4096)];
            let text = String::from_utf8_lossy(head);
            if text
                .lines()
                .any(|l| l.trim_start().starts_with("element chunk"))
            {
                return unsupported("a PlayCanvas compressed PLY (element chunk)");
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
            found: "a SALVQ stream",
            hint: "it is already encoded: `salvq extract` selects a rate, `salvq decode` \
                   decodes it",
        }),
        _ => Ok(InputKind::Model),
    }
}
