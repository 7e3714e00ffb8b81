//! Decode speed against scene size, both profiles, native and WebAssembly. For each real
//! scene (explicit profile): the stream `salvq encode` writes with its
//! default settings, rate 0 extracted (`salvq extract --rate 0`, what a viewer receives for
//! the best rate), decoded in process with `salvq::Decoder::builder().threads(1 | 2)
//! .gaussians_only(true)` (what a viewer needs; the wasm package decodes so too), the 2-thread
//! decode timed twice in each round (after 50 ms idle, then again at once, its threads awake)
//! and once more, after 50 ms idle, on a pool whose threads are pinned one per CPU
//! ([`pinned_pool`]; beside them, how long each pool's sleeping thread takes to start a job,
//! [`wake_latencies`]); the
//! same stream decoded by salvq-wasm's `decode` in Node, and by its `decodePart` in 1 and 2
//! Node worker threads (§10.3.2: each worker its part of the tiles); the whole `salvq decode s.salvq -o
//! out.ply` command; splat-transform reading the scene's SPZ and SOG (written by it from the
//! same PLY) into a PLY and into `null`; the time to receive the stream's bytes at 50 Mbit/s.
//! For generated anchors-profile scenes (`GenParams::new(N, 1)` without a feature basis,
//! `EncodeOptions::default()`, as `decode_throughput`): the native decode on 1 and 2 threads,
//! the wasm decode with the neural Gaussians a viewer draws (on the main thread and on 1 and
//! 2 workers), and the bare ANS coder (one static model, [`salvq_bench::coder`]) on the stream's own
//! symbols as the floor. Writes `speed.svg` (decode time vs scene size, log-log),
//! `speed.csv` and `speed.txt` to `--out`.
//!
//! Run: `cargo bench -p salvq-bench --bench decode_speed -- --out DIR [--splat-transform CMD]`
//! (needs `target/release/salvq`: `cargo build --release` first; the wasm package is built
//! with cargo into `target/decode_speed/wasm-target` and `wasm-bindgen --target nodejs`).
//! Options: `--data DIR` (default `../shared/data`), `--scenes a,b`, `--anchors 10000,…`,
//! `--rounds N`, `--no-wasm`, `--fresh` (re-encode instead of reusing the streams cached in
//! `target/decode_speed/cache`). Relative `--out` and `--data` are taken from the workspace
//! root. `--smoke`: fruit_drops and a 2 000-anchor scene, 3 rounds,
//! wasm only with `SALVQ_BENCH_WASM=1`.
//!
//! Checks what it measures (any difference fails): every timed decode (1 and 2 threads,
//! pinned or not, the wasm package, its workers' parts put back in stream order, the CLI's PLY) equals the reference decode of the same stream (one thread);
//! the explicit stream holds N · (sum of its groups' dimensions) lattice coordinates, of
//! which it codes a symbol for at most that many (§3.5: not the `sh_rest` values after each
//! Gaussian's count; the floor times the coded ones); the
//! anchors stream's symbols are N · (F + S) plus 3 per set offset mask bit, and equal the
//! encoder's count when it was encoded in this run; splat-transform's PLYs hold N Gaussians;
//! the wake-up times fall within the 10 ms that cap them.
//! Times are medians over rounds in one process; the rounds interleave the measurements so
//! that load on a shared machine reaches each alike: the in-process decodes in rounds of
//! their own, after one untimed round, then the commands (salvq's and splat-transform's) in
//! theirs.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use salvq::Decoder;
use salvq::Scene;
use salvq_bench::coder::{bare_coder_decode_ns, median};
use salvq_bitstream::entropy::GaussianTables;
use salvq_bitstream::explicit::Gaussians;

mod anchors;
mod commands;
mod output;
mod wasm;

use anchors::anchors_scene;
use commands::{command_times, explicit_stream, peer_files};
use output::{chart, csv, report};
use wasm::{build_wasm, wasm_times};

/// The link a viewer receives the stream over: 50 Mbit/s.
const LINK_BITS_PER_S: f64 = 50e6;
/// The pause before a round's first 2-thread decode and before the pinned one. On this VM a
/// pool thread woken after the machine had been idle often waited milliseconds on its
/// waker's CPU ([`pinned_pool`]); back to back, the machine busy, it rarely did, so a
/// 2-thread decode right after the 1-thread one measured less than a viewer's single decode
/// meets.
const IDLE_BEFORE_TWO: std::time::Duration = std::time::Duration::from_millis(50);
/// The target: the native decode on 2 threads at least this many Gaussians per second.
const GOAL_GAUSSIANS_PER_S: f64 = 2e6;

type Res<T> = Result<T, Box<dyn std::error::Error>>;

struct Args {
    smoke: bool,
    out: PathBuf,
    data: PathBuf,
    scenes: Vec<String>,
    anchors: Vec<u32>,
    rounds: usize,
    splat_transform: Option<String>,
    wasm: bool,
    fresh: bool,
}

fn args() -> Args {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut a = Args {
        smoke: false,
        out: target_dir().join("decode_speed/out"),
        data: root.join("../shared/data"),
        scenes: ["fruit_drops", "donut", "alti", "guitar"]
            .map(String::from)
            .to_vec(),
        anchors: vec![10_000, 30_000, 100_000, 300_000],
        rounds: 0,
        splat_transform: std::env::var("SALVQ_SPLAT_TRANSFORM").ok(),
        wasm: true,
        fresh: false,
    };
    let list = |s: Option<String>| -> Vec<String> {
        s.unwrap_or_default()
            .split(',')
            .filter(|x| !x.is_empty())
            .map(String::from)
            .collect()
    };
    let mut it = std::env::args().skip(1);
    while let Some(arg) = it.next() {
        match arg.as_str() {
            "--smoke" => a.smoke = true,
            // cargo runs a bench in its package's folder: relative paths are taken from the
            // workspace root instead.
            "--out" => a.out = root.join(it.next().expect("--out DIR")),
            "--data" => a.data = root.join(it.next().expect("--data DIR")),
            "--scenes" => a.scenes = list(it.next()),
            "--anchors" => {
                a.anchors = list(it.next())
                    .iter()
                    .map(|s| s.parse().expect("--anchors N,N,…"))
                    .collect();
            }
            "--rounds" => a.rounds = it.next().and_then(|s| s.parse().ok()).expect("--rounds N"),
            "--splat-transform" => a.splat_transform = it.next(),
            "--no-wasm" => a.wasm = false,
            "--fresh" => a.fresh = true,
            // cargo bench passes `--bench` to a harness-less bench.
            "--bench" => {}
            other => panic!("unknown argument {other}"),
        }
    }
    if a.smoke {
        a.scenes = vec!["fruit_drops".into()];
        a.anchors = vec![2_000];
        a.wasm = std::env::var("SALVQ_BENCH_WASM").is_ok_and(|v| v == "1");
        a.out = target_dir().join("decode_speed/smoke");
    }
    if a.rounds == 0 {
        a.rounds = if a.smoke { 3 } else { 7 };
    }
    a
}

/// A pool of `threads` threads, thread `i` pinned to the `i`-th CPU this process may run on
/// (`None` where there are fewer CPUs or pinning fails). Why: this VM's kernel packs tasks
/// onto few vCPUs (`sched_vcpu_pack` on its command line), so a pool thread woken by a busy
/// thread was queued on the waker's CPU and waited there for a scheduler tick: a sleeping
/// thread took a median 1.9 ms to run, 0.09 ms when the two were pinned to different CPUs
/// (this bench's wake-up latency line). The unpinned decode is what the machine's scheduler
/// gives; the pinned one, what the decoder's two threads do on two CPUs.
fn pinned_pool(threads: usize) -> Option<Arc<rayon::ThreadPool>> {
    let cores = core_affinity::get_core_ids()?;
    if cores.len() < threads {
        return None;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .ok()?;
    let pinned = pool.broadcast(|t| core_affinity::set_for_current(cores[t.index()]));
    pinned.into_iter().all(|ok| ok).then(|| Arc::new(pool))
}

/// How long a sleeping pool thread takes to start a job while the thread that handed it over
/// keeps working: the median over `tries` of the time from a `rayon::join` on one of the
/// pool's 2 threads to its second half starting (taken by the other thread, or by the same
/// one once the first half's 10 ms of spinning end: the measure is capped there). Each try
/// starts after [`IDLE_BEFORE_TWO`] of idle, so the pool's threads are asleep; the two pools
/// take turns, after 5 untimed tries each (a pool's first tries, its threads new, started
/// sooner). For the unpinned pool and for [`pinned_pool`]'s (`None`: none).
fn wake_latencies(tries: usize) -> (f64, Option<f64>) {
    let once = |pool: &rayon::ThreadPool| {
        std::thread::sleep(IDLE_BEFORE_TWO);
        pool.install(|| {
            let t = Instant::now();
            let spin = || while t.elapsed().as_millis() < 10 {};
            rayon::join(spin, || t.elapsed().as_secs_f64()).1
        })
    };
    let Ok(free) = rayon::ThreadPoolBuilder::new().num_threads(2).build() else {
        return (f64::NAN, None);
    };
    let pinned = pinned_pool(2);
    let (mut a, mut b) = (Vec::with_capacity(tries), Vec::with_capacity(tries));
    for i in 0..5 + tries {
        let (x, y) = (once(&free), pinned.as_deref().map(once));
        if i >= 5 {
            a.push(x);
            b.extend(y);
        }
    }
    (median(&mut a), (!b.is_empty()).then(|| median(&mut b)))
}

/// The target folder this bench runs from (`target/release/deps/decode_speed-…`).
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the bench's path");
    exe.ancestors()
        .nth(3)
        .map(Path::to_path_buf)
        .expect("target/<profile>/deps/<bench>")
}

fn secs(f: impl FnOnce()) -> f64 {
    timed(f).0
}

/// One round's in-process decodes, each by `decode` (timed and checked): 1 thread (`d1`);
/// 2 threads (`d2`) after [`IDLE_BEFORE_TWO`] idle, then again at once; 2 pinned threads
/// after idle again, where there is a pinned pool. Their seconds, in that order.
fn round_times(
    d1: &Decoder,
    d2: &Decoder,
    pinned: Option<&Decoder>,
    decode: impl Fn(&Decoder, &str) -> f64,
) -> (f64, f64, f64, Option<f64>) {
    let one = decode(d1, "1-thread decode");
    std::thread::sleep(IDLE_BEFORE_TWO);
    let two = decode(d2, "2-thread decode");
    let again = decode(d2, "2-thread decode, again,");
    let pinned = pinned.map(|d| {
        std::thread::sleep(IDLE_BEFORE_TWO);
        decode(d, "2-thread decode on pinned threads")
    });
    (one, two, again, pinned)
}

/// One decode of `stream` by `d`, timed; its output checked with `same` and dropped outside
/// the timing. `what` names the decode in the failure.
fn checked_decode(
    d: &Decoder,
    stream: &[u8],
    same: impl Fn(&salvq::Result<Scene>) -> bool,
    what: &str,
) -> f64 {
    let (t, got) = timed(|| d.decode(stream));
    assert!(same(&got), "{what} equals the reference");
    drop(got);
    t
}

/// `f`'s wall time and its result (dropped by the caller, outside the timing).
fn timed<T>(f: impl FnOnce() -> T) -> (f64, T) {
    let t = Instant::now();
    let r = f();
    (t.elapsed().as_secs_f64(), r)
}

/// A decode's Gaussians as the wasm package hands them out, float32 little-endian (see
/// `wasm/decode_time.cjs`).
fn dump(g: &Gaussians) -> Vec<u8> {
    let mut v = Vec::new();
    let mut put = |x: &f32| v.extend_from_slice(&x.to_le_bytes());
    g.positions.iter().flatten().for_each(&mut put);
    g.log_scales.iter().flatten().for_each(&mut put);
    g.rotations.iter().flatten().for_each(&mut put);
    g.opacity_logit.iter().for_each(&mut put);
    g.f_dc.iter().flatten().for_each(&mut put);
    g.f_rest.iter().for_each(&mut put);
    v
}

/// The bare coder's floor for `symbols`: its median nanoseconds per symbol (`constriction`,
/// one static model at the tables' precision P) times the count of ALL the symbols, and
/// how many symbols the timing left out: one static model spans fewer than 2^P values, so
/// symbols with |u| ≥ 2^(P−1) − 1 (the escapes' tails) are not timed, but still counted.
fn floor(symbols: &[i64], rounds: usize) -> (Option<f64>, usize) {
    let precision = GaussianTables::standard().precision();
    let h = (1i64 << (precision - 1)) - 1;
    let timed: Vec<i64> = symbols.iter().copied().filter(|u| u.abs() < h).collect();
    if timed.is_empty() {
        return (None, symbols.len());
    }
    let ns = bare_coder_decode_ns(&timed, precision, rounds);
    (
        Some(ns * 1e-9 * symbols.len() as f64),
        symbols.len() - timed.len(),
    )
}

/// One scene's measurements (times in seconds, medians over the rounds).
#[derive(Default, Clone)]
struct Row {
    profile: &'static str,
    scene: String,
    /// Gaussians (explicit) or anchors (anchors profile).
    size: usize,
    /// Entropy-coded symbols the bare coder's floor counts: the explicit stream's coded
    /// symbols (§3.5), the anchors stream's attribute symbols.
    symbols: usize,
    bytes: u64,
    tiles: usize,
    one: f64,
    /// 2 threads, after [`IDLE_BEFORE_TWO`] idle: a viewer's one decode on an idle machine,
    /// its pool's threads asleep.
    two: f64,
    /// 2 threads again at once, the same decoder: its threads awake and the stream in cache.
    two_again: f64,
    /// 2 threads on [`pinned_pool`]'s threads, after [`IDLE_BEFORE_TWO`] idle as `two`
    /// (`None`: fewer than 2 CPUs to pin to).
    two_pinned: Option<f64>,
    /// Median over rounds of (2 threads / 1 thread).
    two_over_one: f64,
    /// The bare coder on the same symbols (`None`: their alphabet is wider than the tables'
    /// precision).
    floor: Option<f64>,
    /// Symbols left out of the bare coder's timing (see [`floor`]).
    floor_outside: usize,
    /// salvq-wasm's `decode` in Node: median of the runs after the first, and the first.
    wasm: Option<(f64, f64)>,
    /// salvq-wasm's `decodePart` in 1 and 2 Node worker threads (§10.3.2), until the arrays
    /// reach the main thread (anchors: with their neural Gaussians): medians of the runs
    /// after the first.
    wasm_workers: Option<[f64; 2]>,
    /// Native equivalent of the wasm call (anchors: decode + neural Gaussians of camera 0,
    /// one thread; explicit: = `one`).
    wasm_native: f64,
    /// `salvq decode s.salvq -o out.ply`, whole process.
    command: Option<f64>,
    /// splat-transform, whole process: SPZ → PLY, SOG → PLY, SPZ → null, SOG → null,
    /// `--version` (node startup).
    peers: Option<[f64; 5]>,
}

impl Row {
    fn receive(&self) -> f64 {
        self.bytes as f64 * 8.0 / LINK_BITS_PER_S
    }
}

fn main() -> Res<()> {
    let a = args();
    std::fs::create_dir_all(&a.out)?;
    let cache = target_dir().join("decode_speed/cache");
    std::fs::create_dir_all(&cache)?;
    let salvq = std::env::var_os("SALVQ")
        .map(PathBuf::from)
        .unwrap_or_else(|| target_dir().join("release/salvq"));
    if !a.scenes.is_empty() && !salvq.exists() {
        return Err(format!(
            "{} not found: run `cargo build --release` first (or set SALVQ)",
            salvq.display()
        )
        .into());
    }
    let pkg = if a.wasm { Some(build_wasm()?) } else { None };
    let wake = wake_latencies(if a.smoke { 5 } else { 15 });
    assert!(
        wake.0 > 0.0 && wake.0 < 0.011 && wake.1.is_none_or(|p| p > 0.0 && p < 0.011),
        "a join's second half starts within its first half's 10 ms: {wake:?}"
    );
    let mut rows = Vec::new();
    for scene in &a.scenes {
        let ply = a.data.join(format!("{scene}.ply"));
        if !ply.exists() {
            // On stderr: CI keeps only some lines of stdout.
            eprintln!("skipped {scene}: {} not found", ply.display());
            continue;
        }
        rows.push(explicit_scene(
            &a,
            scene,
            &ply,
            &salvq,
            &cache,
            pkg.as_deref(),
        )?);
    }
    for &n in &a.anchors {
        rows.push(anchors_scene(&a, n, &cache, pkg.as_deref())?);
    }
    let text = report(&a, &rows, wake);
    print!("{text}");
    std::fs::write(a.out.join("speed.txt"), &text)?;
    std::fs::write(a.out.join("speed.csv"), csv(&rows))?;
    chart(&a.out.join("speed.svg"), &rows, a.wasm)?;
    println!(
        "wrote speed.svg, speed.csv, speed.txt to {}",
        a.out.display()
    );
    Ok(())
}

/// An explicit scene's row before its timings: its size and tiles from the reference decode,
/// checked (§3.3), and the bare coder's floor on the symbols the stream codes (§3.5).
fn explicit_row(
    a: &Args,
    scene: &str,
    reference: &salvq::DecodedGaussians,
    bytes: u64,
) -> Res<Row> {
    let n = reference.gaussians.len();
    // §3.3: every Gaussian codes each group's `dim` lattice coordinates.
    let per: usize = reference.groups.iter().map(|g| g.dim).sum();
    assert_eq!(
        reference.symbols.coords.len(),
        n * per,
        "{scene}: lattice coordinates = N · Σ dims"
    );
    let mut row = Row {
        profile: "explicit",
        scene: scene.into(),
        size: n,
        symbols: reference.symbols.coords.len(),
        bytes,
        tiles: reference.tiles.len(),
        ..Row::default()
    };
    // The floor: the symbols GATT codes (§3.5: not the sh_rest values after each Gaussian's
    // count), in stream order.
    let coded = salvq_encoder::info::explicit::coded_symbols(reference)?;
    assert!(
        coded.len() <= reference.symbols.coords.len(),
        "{scene}: coded symbols ≤ values"
    );
    row.symbols = coded.len();
    (row.floor, row.floor_outside) = floor(&coded, a.rounds);
    Ok(row)
}

/// One real scene's row (explicit profile): its rate-0 stream decoded in process, by
/// `salvq decode`, by splat-transform from its own files and in the wasm package, each timed
/// and checked against the reference decode.
fn explicit_scene(
    a: &Args,
    scene: &str,
    ply: &Path,
    salvq: &Path,
    cache: &Path,
    pkg: Option<&Path>,
) -> Res<Row> {
    let path = explicit_stream(a, scene, ply, salvq, cache)?;
    let stream = std::fs::read(&path)?;
    let one_opts = salvq::Decoder::builder().threads(1);
    let salvq::Scene::Gaussians(reference) = one_opts.build().decode(&stream)? else {
        return Err(format!("{}: not an explicit-profile stream", path.display()).into());
    };
    let n = reference.gaussians.len();
    let mut row = explicit_row(a, scene, &reference, stream.len() as u64)?;

    let st = a.splat_transform.as_deref();
    let peer_files = peer_files(a, scene, ply, cache)?;

    // What a viewer decodes: the Gaussians, not the symbols they came from.
    let d1 = Decoder::builder().threads(1).gaussians_only(true).build();
    let d2 = Decoder::builder().threads(2).gaussians_only(true).build();
    let d2p = pinned_pool(2).map(|p| {
        Decoder::builder()
            .thread_pool(p)
            .gaussians_only(true)
            .build()
    });
    let same = |got: &salvq::Result<Scene>| {
        matches!(got, Ok(salvq::Scene::Gaussians(g))
            if g.gaussians == reference.gaussians && g.voxels == reference.voxels)
    };
    // Scratch files stay out of `--out` (which may be docs/).
    let work = target_dir().join("decode_speed/work");
    std::fs::create_dir_all(&work)?;
    let out_ply = work.join(format!("{scene}.decoded.ply"));
    let (mut t1, mut t2, mut t2b, mut ratio) = (vec![], vec![], vec![], vec![]);
    let mut t2p = vec![];
    // One round untimed first, as the commands' timer does (their warm-up run).
    drop((d1.decode(&stream), d2.decode(&stream)));
    drop(d2p.as_ref().map(|d| d.decode(&stream)));
    let decode =
        |d: &Decoder, what: &str| checked_decode(d, &stream, same, &format!("{scene}: the {what}"));
    for _ in 0..a.rounds {
        let (s1, s2, again, pinned) = round_times(&d1, &d2, d2p.as_ref(), decode);
        t2p.extend(pinned);
        t1.push(s1);
        t2.push(s2);
        t2b.push(again);
        ratio.push(s2 / s1);
    }
    let (mut cmd, peers) = command_times(a, salvq, &path, &work, scene, &peer_files, n)?;
    let written = salvq_render::ply::read_ply(&std::fs::read(&out_ply)?)?;
    assert!(
        written == reference.gaussians,
        "{scene}: salvq decode's PLY holds the reference decode"
    );
    row.one = median(&mut t1);
    row.two = median(&mut t2);
    row.two_again = median(&mut t2b);
    row.two_pinned = (!t2p.is_empty()).then(|| median(&mut t2p));
    row.two_over_one = median(&mut ratio);
    row.wasm_native = row.one;
    row.command = Some(median(&mut cmd));
    if st.is_some() {
        row.peers = Some(peers.map(|mut v| median(&mut v)));
    }
    if let Some(pkg) = pkg {
        let expected = dump(&reference.gaussians);
        row.wasm = Some(wasm_times(pkg, &path, a.rounds, &expected, scene, 0)?);
        let on = |workers| wasm_times(pkg, &path, a.rounds, &expected, scene, workers);
        row.wasm_workers = Some([on(1)?.0, on(2)?.0]);
    }
    println!(
        "{scene}: {n} Gaussians, {} B; 1 thread {:.4} s, 2 threads {:.4} s",
        row.bytes, row.one, row.two
    );
    Ok(row)
}
