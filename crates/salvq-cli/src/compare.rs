//! `salvq compare A B`: renders two scenes from the same cameras (a capture's, or the ring
//! around A) and reports PSNR and SSIM per view and overall (spec Annex C.2, C.5).

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use salvq_encoder::Error;
use salvq_render::camera::{Camera, Ring};
use salvq_render::camera_file::{read_colmap_dir, read_inria_json, NamedCamera};
use salvq_render::compare::{RingTarget, ViewScore};
use salvq_render::scene::Scene;
use salvq_render::Gaussians;

use super::render::load;

/// The ring's image size and views when none are given: the yardstick the encoder fits its
/// rates at (Annex A.8.2), so that compare measures what the encoder reports.
use salvq_encoder::explicit::ratios::{
    QUALITY_HEIGHT as RING_HEIGHT, QUALITY_VIEWS as RING_VIEWS, QUALITY_WIDTH as RING_WIDTH,
};

/// Arguments of `salvq compare`.
#[derive(clap::Args)]
pub(crate) struct CompareArgs {
    /// The reference: a SALVQ stream (either profile), a safetensors model or a 3DGS PLY file.
    a: PathBuf,
    /// The scene compared with it, of any of the same kinds.
    b: PathBuf,
    /// Render from the cameras of an Inria 3DGS `cameras.json` (default: the ring around A).
    #[arg(long, conflicts_with = "colmap")]
    cameras: Option<PathBuf>,
    /// Render from the cameras of a COLMAP text model: the folder with `cameras.txt` and
    /// `images.txt` (e.g. `sparse/0`).
    #[arg(long)]
    colmap: Option<PathBuf>,
    /// Ring views (default 8); with real cameras, use this many of them, evenly spread
    /// (default all).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    views: Option<u32>,
    /// Image width (ring default 512). Real cameras keep their own size unless given; with
    /// only one side given the other keeps the camera's aspect ratio.
    #[arg(long)]
    width: Option<u32>,
    /// Image height (ring default 384).
    #[arg(long)]
    height: Option<u32>,
    /// The rate to decode A at, if a stream (default: the finest rate it carries).
    #[arg(long)]
    rate_a: Option<u8>,
    /// The rate to decode B at, if a stream (default: the finest rate it carries).
    #[arg(long)]
    rate_b: Option<u8>,
    /// Print JSON instead of a table (PSNR `null` where the images are identical: MSE 0).
    #[arg(long)]
    json: bool,
}

/// The capture's cameras to render from, `None` for the ring.
fn real_cameras(a: &CompareArgs) -> Result<Option<Vec<NamedCamera>>, Error> {
    let cameras = match (&a.cameras, &a.colmap) {
        (Some(json), _) => read_inria_json(json)?,
        (None, Some(dir)) => read_colmap_dir(dir)?,
        (None, None) => return Ok(None),
    };
    // `views` of them, evenly spread: index ⌊i · n / views⌋.
    let n = cameras.len();
    let keep = a.views.map_or(n, |v| (v as usize).min(n));
    let picked = (0..keep).map(|i| cameras[i * n / keep].clone());
    let sized = picked.map(|c| {
        let camera = resize(&c.camera, a.width, a.height)?;
        Ok(NamedCamera { camera, ..c })
    });
    Ok(Some(sized.collect::<Result<_, Error>>()?))
}

/// A real camera at the size asked for (one side given: the other keeps the aspect ratio).
fn resize(c: &Camera, width: Option<u32>, height: Option<u32>) -> Result<Camera, Error> {
    let scaled = |side: u32, num: u32, den: u32| {
        ((f64::from(side) * f64::from(num) / f64::from(den)).round() as u32).max(1)
    };
    let (w, h) = match (width, height) {
        (None, None) => return Ok(c.clone()),
        (Some(w), Some(h)) => (w, h),
        (Some(w), None) => (w, scaled(c.height, w, c.width)),
        (None, Some(h)) => (scaled(c.width, h, c.height), h),
    };
    Ok(c.resized(w, h)?)
}

fn gaussians_for<'s>(
    scene: &'s Scene,
) -> impl Fn(&Camera) -> salvq_render::Result<Cow<'s, Gaussians>> + 's {
    move |c: &Camera| scene.gaussians(c.position)
}

/// How one view, or all, compares.
#[derive(serde::Serialize)]
struct Score {
    /// Mean squared error, peak 1 (over all views: their mean).
    mse: f64,
    /// `None` (JSON null) where the images are identical (MSE 0, PSNR +∞).
    psnr_db: Option<f64>,
    ssim: f64,
}

impl From<ViewScore> for Score {
    fn from(s: ViewScore) -> Score {
        let psnr = s.psnr();
        Score {
            mse: s.mse,
            psnr_db: psnr.is_finite().then_some(psnr),
            ssim: s.ssim,
        }
    }
}

#[derive(serde::Serialize)]
struct ViewReport {
    view: usize,
    camera: String,
    width: u32,
    height: u32,
    #[serde(flatten)]
    score: Score,
}

#[derive(serde::Serialize)]
struct Report {
    a: String,
    b: String,
    /// `ring` or the camera file.
    cameras: String,
    views: Vec<ViewReport>,
    /// PSNR of the mean MSE over the views, mean SSIM (Annex C.5).
    overall: Score,
}

fn psnr_text(s: &Score) -> String {
    s.psnr_db.map_or("inf".into(), |p| format!("{p:.2}"))
}

/// The report as a table.
fn table(r: &Report) -> String {
    let mut t = format!(
        "A: {}\nB: {}\ncameras: {}\n\n{:>4}  {:<24} {:>11} {:>9} {:>8}\n",
        r.a, r.b, r.cameras, "view", "camera", "size", "PSNR dB", "SSIM"
    );
    for v in &r.views {
        let name: String = v.camera.chars().take(24).collect();
        let size = format!("{}x{}", v.width, v.height);
        t.push_str(&format!(
            "{:>4}  {name:<24} {size:>11} {:>9} {:>8.5}\n",
            v.view,
            psnr_text(&v.score),
            v.score.ssim
        ));
    }
    t.push_str(&format!(
        "{:>4}  {:<24} {:>11} {:>9} {:>8.5}   (PSNR of the mean MSE, mean SSIM)\n",
        "all",
        "",
        "",
        psnr_text(&r.overall),
        r.overall.ssim
    ));
    t
}

fn shown(path: &Path) -> String {
    path.display().to_string()
}

/// `salvq compare`.
pub(crate) fn run(a: CompareArgs) -> Result<(), Error> {
    let real = real_cameras(&a)?;
    let scene_a = load(&a.a, a.rate_a)?;
    let scene_b = load(&a.b, a.rate_b)?;
    let (names, cameras, source): (Vec<String>, Vec<Camera>, String) = match real {
        Some(real) => {
            let file = a.cameras.as_ref().or(a.colmap.as_ref()).map(|p| shown(p));
            let (names, cameras) = real.into_iter().map(|c| (c.name, c.camera)).unzip();
            (names, cameras, file.unwrap_or_default())
        }
        None => {
            let ring = Ring {
                views: a.views.unwrap_or(RING_VIEWS),
                ..Ring::default()
            };
            let (w, h) = (
                a.width.unwrap_or(RING_WIDTH),
                a.height.unwrap_or(RING_HEIGHT),
            );
            // The ring around A (Annex C.2), as `salvq render A` places it.
            let bounds = scene_a.bounds();
            let cameras = (0..ring.views)
                .map(|v| ring.camera(&bounds, v, w, h).map_err(Into::into))
                .collect::<salvq_render::Result<Vec<_>>>()?;
            let names = (0..ring.views).map(|v| format!("ring {v}")).collect();
            let source = format!("ring of {} views around A", ring.views);
            (names, cameras, source)
        }
    };
    let target = RingTarget::from_cameras(cameras, gaussians_for(&scene_a))?;
    let scores = target.view_scores(true, gaussians_for(&scene_b))?;
    let views = scores
        .iter()
        .zip(names)
        .zip(&target.cameras)
        .enumerate()
        .map(|(view, ((&s, camera), c))| ViewReport {
            view,
            camera,
            width: c.width,
            height: c.height,
            score: s.into(),
        })
        .collect();
    let report = Report {
        a: shown(&a.a),
        b: shown(&a.b),
        cameras: source,
        views,
        overall: ViewScore::mean(&scores).into(),
    };
    if a.json {
        out!(
            "{}",
            serde_json::to_string_pretty(&report).unwrap_or_default()
        );
    } else {
        crate::print_text(&table(&report));
    }
    Ok(())
}
