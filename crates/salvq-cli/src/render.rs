//! `salvq render` and `salvq export-ply` (spec Annex C): a preview image of a stream, a model
//! file or a 3DGS PLY file from a camera of the ring, and the standard 3DGS PLY of a stream
//! or model file.

use std::path::PathBuf;
use std::time::Instant;

use salvq_encoder::Error;
use salvq_render::camera::{Axis, Ring};
use salvq_render::scene::Scene;
use salvq_render::{ply, raster};

use super::files::{self, Ctx};
use super::secs;

/// The camera ring's settings (spec Annex C.2).
#[derive(clap::Args)]
pub(crate) struct RingArgs {
    /// Camera I of the ring (0 … N − 1): the view rendered, or for export-ply the camera the
    /// view-dependent MLPs (opacity, colour, covariance) are evaluated from (spec Annex C.1).
    #[arg(long, default_value_t = 0)]
    view: u32,
    /// N: cameras on the ring, evenly spaced.
    #[arg(long, default_value_t = salvq_encoder::explicit::ratios::QUALITY_VIEWS)]
    views: u32,
    /// Elevation of the ring above the scene's centre, degrees.
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
    elevation: f64,
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 50.0)]
    fov: f64,
    /// The scene's up axis: +x, -x, +y, -y, +z or -z (3DGS captures are usually -y up).
    #[arg(long, default_value = "-y", value_parser = parse_axis, allow_hyphen_values = true)]
    up: Axis,
}

impl RingArgs {
    fn ring(&self) -> Ring {
        Ring {
            views: self.views,
            elevation_deg: self.elevation,
            fov_y_deg: self.fov,
            up: self.up,
        }
    }
}

/// Arguments of `salvq render`.
#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// Input: a SALVQ stream, a safetensors model (spec Annex A) or a 3DGS PLY file (`-`:
    /// standard input).
    input: PathBuf,
    /// Output image (PNG, 8-bit RGB; default: the input's name with `.view<I>.png`; `-`:
    /// standard output).
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// The rate to decode a stream at (default: the finest rate it carries).
    #[arg(long)]
    rate: Option<u8>,
    #[command(flatten)]
    ring: RingArgs,
    /// Image width in pixels.
    #[arg(long, default_value_t = salvq_encoder::explicit::ratios::QUALITY_WIDTH)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = salvq_encoder::explicit::ratios::QUALITY_HEIGHT)]
    height: u32,
    /// Background colour `r,g,b`, each in [0, 1].
    #[arg(long, default_value = "0,0,0", value_parser = parse_rgb)]
    background: [f32; 3],
    /// Render on N threads (default: all cores; the image is the same for every N).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    threads: Option<u32>,
    /// Print what was rendered as JSON on standard output.
    #[arg(long)]
    json: bool,
}

/// Arguments of `salvq export-ply`.
#[derive(clap::Args)]
pub(crate) struct ExportPlyArgs {
    /// Input: a SALVQ stream or a safetensors model (spec Annex A; `-`: standard input).
    input: PathBuf,
    /// Output PLY file (Inria 3DGS layout, spec Annex C.3; default: the input's name with
    /// `.ply`; `-`: standard output).
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// The rate to decode a stream at (default: the finest rate it carries).
    #[arg(long)]
    rate: Option<u8>,
    /// The ring camera that the view-dependent MLPs are evaluated from (spec Annex C.1, C.2).
    #[command(flatten)]
    ring: RingArgs,
    /// Print what was exported as JSON on standard output.
    #[arg(long)]
    json: bool,
}

/// What `--json` prints of `render` and `export-ply`.
#[derive(serde::Serialize)]
struct Written {
    output: String,
    view: u32,
    views: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    width: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    height: Option<u32>,
    gaussians: u64,
    seconds: f64,
}

fn parse_axis(s: &str) -> Result<Axis, String> {
    Axis::parse(s).ok_or_else(|| format!("`{s}`: expected +x, -x, +y, -y, +z or -z"))
}

fn parse_rgb(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().map_err(|e| format!("'{x}': {e}")))
        .collect::<Result<_, _>>()?;
    let rgb: [f32; 3] = v
        .try_into()
        .map_err(|v: Vec<f32>| format!("3 numbers expected, {} given", v.len()))?;
    if rgb.iter().any(|c| !(0.0..=1.0).contains(c)) {
        return Err("each channel is in [0, 1]".into());
    }
    Ok(rgb)
}

/// Runs `f` on a pool of `threads` threads, or on rayon's global pool.
fn with_threads<T: Send>(threads: Option<u32>, f: impl FnOnce() -> T + Send) -> T {
    let pool = threads.and_then(|n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build()
            .ok()
    });
    match pool {
        Some(p) => p.install(f),
        None => f(),
    }
}

/// The scene in a stream, model or PLY file (`rate`: a stream's rate to decode).
pub(crate) fn load(input: &std::path::Path, rate: Option<u8>) -> Result<Scene, Error> {
    Ok(Scene::from_bytes(&files::read_input(input)?, rate)?)
}

/// `salvq render`.
pub(crate) fn render(a: RenderArgs, ctx: Ctx) -> Result<(), Error> {
    let t = Instant::now();
    let extension = format!("view{}.png", a.ring.view);
    let output = ctx.output(a.output.as_deref(), &a.input, &extension, &[&a.input])?;
    output.require_extension(&["png"], "render writes a PNG image", ".png")?;
    files::json_beside(a.json, &output);
    let scene = load(&a.input, a.rate)?;
    let load_secs = secs(t);
    let camera = a
        .ring
        .ring()
        .camera(&scene.bounds(), a.ring.view, a.width, a.height)?;
    let (image, stats, gen_secs, raster_secs) = with_threads(a.threads, || {
        let t = Instant::now();
        let gaussians = scene.gaussians(camera.position)?;
        let gen_secs = secs(t);
        let t = Instant::now();
        let (image, stats) = raster::render_with_stats(&gaussians, &camera, a.background);
        Ok::<_, Error>((image, stats, gen_secs, secs(t)))
    })?;
    let png = image.to_png()?;
    output.write_bytes(&png)?;
    let source = match &scene {
        Scene::Model(m) => format!(
            "{} anchors -> neural Gaussians in {:.1} ms",
            m.dims.anchors,
            gen_secs * 1e3
        ),
        Scene::Gaussians { gaussians: g, .. } => {
            format!("{} Gaussians (SH degree {})", g.len(), g.sh_degree)
        }
    };
    if a.json {
        files::print_json(&Written {
            output: output.shown(),
            view: a.ring.view,
            views: a.ring.views,
            width: Some(a.width),
            height: Some(a.height),
            gaussians: stats.splats as u64,
            seconds: secs(t),
        });
    }
    ctx.say(&format!(
        "rendered view {} of {} ({}x{}) into {}: {source}; {} drawn, {} tile entries; \
         read in {:.1} ms, rasterized in {:.1} ms",
        a.ring.view,
        a.ring.views,
        a.width,
        a.height,
        output.shown(),
        stats.splats,
        stats.tile_entries,
        load_secs * 1e3,
        raster_secs * 1e3
    ));
    Ok(())
}

/// `salvq export-ply`.
pub(crate) fn export_ply(a: ExportPlyArgs, ctx: Ctx) -> Result<(), Error> {
    let t = Instant::now();
    let output = ctx.output(a.output.as_deref(), &a.input, "ply", &[&a.input])?;
    output.require_extension(&["ply"], "export-ply writes a 3DGS PLY", ".ply")?;
    files::json_beside(a.json, &output);
    let bytes = files::read_input(&a.input)?;
    let scene = Scene::from_bytes(&bytes, a.rate)?;
    let written = |gaussians: usize| Written {
        output: output.shown(),
        view: a.ring.view,
        views: a.ring.views,
        width: None,
        height: None,
        gaussians: gaussians as u64,
        seconds: secs(t),
    };
    let model = match &scene {
        Scene::Model(m) => m,
        // An explicit-profile stream (spec §3): its Gaussians are the export.
        Scene::Gaussians { gaussians: g, .. }
            if salvq_bitstream::container::is_explicit(&bytes) =>
        {
            output.write(|w| ply::write_ply(g, w))?;
            if a.json {
                files::print_json(&written(g.len()));
            }
            ctx.say(&format!(
                "exported {} Gaussians (SH degree {}) into {} in {:.2} s",
                g.len(),
                g.sh_degree,
                output.shown(),
                secs(t)
            ));
            return Ok(());
        }
        Scene::Gaussians { .. } => {
            return Err(salvq_render::Error::RenderSettingInvalid {
                setting: "input",
                value: 0.0,
                rule: "export-ply reads a SALVQ stream or a safetensors model, not a PLY file",
            }
            .into())
        }
    };
    // The camera position does not depend on the image size; any valid size will do.
    let bounds = scene.bounds();
    let camera = a.ring.ring().camera(&bounds, a.ring.view, 512, 384)?;
    let gaussians = salvq_render::neural::neural_gaussians(model, camera.position)?;
    // The anchors' bounds go with the PLY, so that its ring is the model's (Annex C.3).
    output.write(|w| ply::write_ply_with(&gaussians, Some(&bounds), w))?;
    if a.json {
        files::print_json(&written(gaussians.len()));
    }
    let unmasked = model.anchors.mask.iter().filter(|&&m| m == 1).count();
    ctx.say(&format!(
        "exported {} Gaussians into {} in {:.2} s: the unmasked offsets ({unmasked}) of {} anchors \
         with opacity > 0 seen from ring camera {} of {} at {:?}",
        gaussians.len(),
        output.shown(),
        secs(t),
        model.dims.anchors,
        a.ring.view,
        a.ring.views,
        camera.position,
    ));
    Ok(())
}
