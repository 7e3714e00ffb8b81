//! PlayCanvas splat-transform's formats as peers (Annex A.8.4): a scene written by it in one
//! format (timed), read back to PLY (timed), and rendered against the input's reference.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use salvq_encoder::{Error, Result};
use salvq_render::compare::RingTarget;
use salvq_render::error::IoOp;
use salvq_render::ply::read_ply;

/// What one peer format did to a scene.
#[derive(Debug, Clone, Copy)]
pub struct PeerResult {
    /// The encoded file's bytes.
    pub bytes: u64,
    /// Render PSNR of it decoded, against the reference.
    pub psnr_db: f64,
    /// SSIM of it decoded.
    pub ssim: f64,
    /// Wall seconds of splat-transform writing it, and of reading it back to PLY.
    pub encode_s: f64,
    pub decode_s: f64,
}

/// One peer format through splat-transform `st` (a command line, e.g. a path to its
/// `.bin/splat-transform`): encode (timed), decode back to PLY (timed), render against
/// `reference`. Files go to `work`; `None` when splat-transform cannot write the format.
pub fn peer_encode(
    st: &str,
    scene: &str,
    input: &Path,
    format: &str,
    work: &Path,
    reference: &RingTarget,
) -> Result<Option<PeerResult>> {
    let encoded = work.join(format!("{scene}.{format}"));
    let decoded = work.join(format!("{scene}.{format}.ply"));
    let run = |args: &[&std::ffi::OsStr]| -> Result<(bool, f64)> {
        let mut parts = st.split_whitespace();
        let program = parts.next().unwrap_or("splat-transform");
        let t = Instant::now();
        let status = Command::new(program)
            .args(parts)
            .args(args)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .status()
            .map_err(|e| Error::io(IoOp::Write, Path::new(program), e))?;
        Ok((status.success(), t.elapsed().as_secs_f64()))
    };
    let mut enc_args: Vec<&std::ffi::OsStr> = vec!["-q".as_ref(), "-w".as_ref()];
    if format == "sog" {
        enc_args.push(std::ffi::OsStr::new("-g"));
        enc_args.push(std::ffi::OsStr::new("cpu"));
    }
    enc_args.push(input.as_os_str());
    enc_args.push(encoded.as_os_str());
    let (ok, encode_s) = run(&enc_args)?;
    if !ok {
        return Ok(None);
    }
    let (ok, decode_s) = run(&[
        "-q".as_ref(),
        "-w".as_ref(),
        encoded.as_os_str(),
        decoded.as_os_str(),
    ])?;
    if !ok {
        return Ok(None);
    }
    let bytes = std::fs::metadata(&encoded)
        .map_err(|e| Error::io(IoOp::Read, &encoded, e))?
        .len();
    let g = read_ply(&salvq_render::io::read_file(&decoded)?)?;
    let (psnr_db, ssim) = reference.psnr_ssim(&g)?;
    Ok(Some(PeerResult {
        bytes,
        psnr_db,
        ssim,
        encode_s,
        decode_s,
    }))
}
