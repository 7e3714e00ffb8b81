//! The decode_speed bench's commands, each run and timed as a whole process: `salvq encode`,
//! `extract` and `decode`, and splat-transform's conversions (its peers).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use super::{Args, Res};

/// Runs a command with its output discarded; the wall time of the whole process.
fn run_timed(cmd: &mut Command) -> Res<f64> {
    let t = Instant::now();
    let out = cmd.stdout(Stdio::null()).stderr(Stdio::piped()).output()?;
    let s = t.elapsed().as_secs_f64();
    if !out.status.success() {
        return Err(format!(
            "{cmd:?} failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )
        .into());
    }
    Ok(s)
}

/// The command line of `st` (e.g. `node path/cli.mjs` or a path).
fn st_command(st: &str) -> Command {
    let mut parts = st.split_whitespace();
    let mut c = Command::new(parts.next().unwrap_or("splat-transform"));
    c.args(parts);
    c
}

/// The rate-0 stream of `scene` with default settings, from the cache or encoded now.
pub(crate) fn explicit_stream(
    a: &Args,
    scene: &str,
    ply: &Path,
    salvq: &Path,
    cache: &Path,
) -> Res<PathBuf> {
    let all = cache.join(format!("{scene}.salvq"));
    let r0 = cache.join(format!("{scene}.r0.salvq"));
    if a.fresh || !r0.exists() {
        println!("{scene}: salvq encode (default settings) …");
        let t = run_timed(
            // --force: a fresh encode replaces the cached streams.
            Command::new(salvq)
                .arg("encode")
                .arg(ply)
                .arg("-o")
                .arg(&all)
                .arg("--force"),
        )?;
        run_timed(
            Command::new(salvq)
                .arg("extract")
                .arg(&all)
                .args(["--rate", "0", "-o"])
                .arg(&r0)
                .arg("--force"),
        )?;
        println!("{scene}: encoded in {t:.1} s");
    }
    Ok(r0)
}

/// The peers' files of `scene` (SPZ, SOG), written once from the same PLY by splat-transform
/// when it is given.
pub(crate) fn peer_files(a: &Args, scene: &str, ply: &Path, cache: &Path) -> Res<Vec<PathBuf>> {
    let mut files = Vec::new();
    if let Some(st) = a.splat_transform.as_deref() {
        for format in ["spz", "sog"] {
            let f = cache.join(format!("{scene}.{format}"));
            if a.fresh || !f.exists() {
                let mut c = st_command(st);
                c.args(["-q", "-w"]);
                if format == "sog" {
                    c.args(["-g", "cpu"]);
                }
                run_timed(c.arg(ply).arg(&f))?;
            }
            files.push(f);
        }
    }
    Ok(files)
}

/// Seconds of `salvq decode` to a PLY per round, and of the peers' commands: each peer file
/// to a PLY, to nothing, and splat-transform's start-up (`--version`).
pub(crate) fn command_times(
    a: &Args,
    salvq: &Path,
    path: &Path,
    work: &Path,
    scene: &str,
    peer_files: &[PathBuf],
    n: usize,
) -> Res<(Vec<f64>, [Vec<f64>; 5])> {
    let out_ply = work.join(format!("{scene}.decoded.ply"));
    let peer_ply = work.join(format!("{scene}.peer.ply"));
    let (mut cmd, mut peers): (Vec<f64>, [Vec<f64>; 5]) = Default::default();
    // The commands in rounds of their own: on this VM a 2-thread decode in process ran
    // slower for a while after Node had run.
    for _ in 0..a.rounds {
        cmd.push(run_timed(
            // Each round replaces the last one's PLY, as splat-transform's `-w` below.
            Command::new(salvq)
                .arg("decode")
                .arg(path)
                .arg("-o")
                .arg(&out_ply)
                .arg("--force"),
        )?);
        if let Some(st) = a.splat_transform.as_deref() {
            for (i, f) in peer_files.iter().enumerate() {
                peers[i].push(run_timed(
                    st_command(st).args(["-q", "-w"]).arg(f).arg(&peer_ply),
                )?);
                let written = salvq_render::ply::read_ply_lenient(&std::fs::read(&peer_ply)?)?;
                assert_eq!(written.len(), n, "{scene}: splat-transform's PLY holds N");
                peers[2 + i].push(run_timed(st_command(st).arg("-q").arg(f).arg("null"))?);
            }
            peers[4].push(run_timed(st_command(st).arg("--version"))?);
        }
    }
    Ok((cmd, peers))
}
