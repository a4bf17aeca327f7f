//! `aether`: render a Mitsuba scene, or the built-in Cornell box.

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use aether_strategies::scene::{Film, Scene};
use clap::{Parser, Subcommand, ValueEnum};
use integrators::bdpt::Bdpt;
use integrators::cornell::cornell_box;
use integrators::gradient::{GradientPathTracer, render_gradients};
use integrators::mlt::{MltSettings, Variant, render_mlt};
use integrators::output::{
    Comparison, OutputFiles, read_exr, write_exr, write_exr_with_counts, write_png,
};
use integrators::parts::put_render;
use integrators::render::{Settings, render, render_with};
use integrators::shard::Shard;
use integrators::shard_file::{merge_files, read_part, write_part};

#[derive(Parser, Debug)]
#[command(
    name = "aether",
    version,
    about = "Monte Carlo light transport in the Aether sampling language"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a scene (the built-in Cornell box without one) to EXR and PNG.
    Render(Box<RenderArgs>),
    /// Compare EXR images with a reference: means, their relative difference
    /// and RMSE (and, for parts of renders, whether they are the same part).
    Compare {
        /// The reference image.
        reference: PathBuf,
        /// Images of the same size.
        images: Vec<PathBuf>,
    },
    /// Merge the parts of a render (`render --shard K/N`) into its image.
    Merge {
        /// The image to write (`x.exr` or `x.png`, the other beside it).
        output: PathBuf,
        /// The parts, in any order.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        /// Merge the parts given even if some are missing.
        #[arg(long)]
        partial: bool,
        /// Overwrite an existing output.
        #[arg(long)]
        force: bool,
        /// Exposure of the PNG preview, in stops.
        #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
        exposure: f32,
    },
}

fn merge(
    output: &std::path::Path,
    parts: &[PathBuf],
    partial: bool,
    force: bool,
    exposure: f32,
) -> Result<(), String> {
    let report = merge_files(output, parts, partial, force, exposure)?;
    let names: Vec<String> = report
        .written
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    println!(
        "{}: {} parts, {:.0} samples{}",
        names.join(", "),
        parts.len(),
        report.samples,
        match report.fraction {
            f if f < 1.0 => format!(" ({:.1} % of the render's parts)", 100.0 * f),
            _ => String::new(),
        }
    );
    Ok(())
}

fn compare(reference: &std::path::Path, images: &[PathBuf]) -> Result<(), String> {
    let (w, h, r) = read_exr(reference)?;
    for path in images {
        let (iw, ih, image) = read_exr(path)?;
        let c = Comparison::of(&image, &r)
            .filter(|_| (iw, ih) == (w, h))
            .ok_or_else(|| {
                format!(
                    "{}: {iw}×{ih}, but the reference is {w}×{h}",
                    path.display()
                )
            })?;
        println!(
            "{}: mean {:.6} (reference {:.6}, {:+.3} %), RMSE {:.6}",
            path.display(),
            c.mean,
            c.reference_mean,
            100.0 * c.relative_difference(),
            c.rmse
        );
        // Two parts of renders: are they the same part, sums and all?
        if let (Ok(a), Ok(b)) = (read_part(reference), read_part(path)) {
            match a == b {
                true => println!(
                    "{}: the same part {}, every sum and count equal",
                    path.display(),
                    b.0
                ),
                false => println!("{}: a different part from the reference", path.display()),
            }
        }
    }
    Ok(())
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Integrator {
    Path,
    Light,
    Direct,
    Bdpt,
    Tridir,
    /// Gradient-domain path tracing: writes the reconstruction, and the
    /// primal and gradient images beside it.
    Gpt,
    /// Veach's path-space Metropolis light transport; `--spp` counts
    /// mutations per pixel.
    Mlt,
    /// Primary-sample-space Metropolis light transport on BDPT; `--spp`
    /// counts mutations per pixel.
    Pssmlt,
    /// Multiplexed Metropolis light transport on BDPT; `--spp` counts
    /// mutations per pixel.
    Mmlt,
}

#[derive(clap::Args, Debug)]
struct RenderArgs {
    /// A Mitsuba 0.5/0.6 scene file; without one, the built-in Cornell box.
    scene: Option<PathBuf>,
    /// The integrator (default: the scene's).
    #[arg(short, long, value_enum)]
    integrator: Option<Integrator>,
    /// Samples per pixel (default: the scene's).
    #[arg(long)]
    spp: Option<u32>,
    /// Maximum path depth, as Mitsuba counts it (1: emitters seen directly, 2: direct lighting, -1: unlimited).
    #[arg(long, allow_hyphen_values = true)]
    max_depth: Option<i64>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seed of the random streams.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Stop after this many seconds, keeping what was rendered (Metropolis
    /// methods finish their bootstrap and a first batch of mutations first).
    #[arg(long)]
    time_limit: Option<f64>,
    /// Output image: `x.exr` (linear HDR) or `x.png` (sRGB preview); the other
    /// is written beside it with the same name.
    #[arg(short, long, default_value = "out.exr")]
    output: PathBuf,
    /// Exposure of the PNG preview, in stops.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// Scene parameter, as name=value (overrides the file's `<default>`).
    #[arg(short = 'D', value_parser = parse_param)]
    define: Vec<(String, String)>,
    /// Also write BDPT's (s, t) technique images, weighted and unweighted, into this folder.
    #[arg(long)]
    techniques: Option<PathBuf>,
    /// Longest paths, in vertices, with technique images.
    #[arg(long, default_value_t = 5)]
    technique_vertices: usize,
    /// PSSMLT and MMLT: probability of a large step (default: the scene's pLarge, or 0.3).
    #[arg(long)]
    large_step: Option<f64>,
    /// Metropolis: independent chains; the image depends on them, not on
    /// the threads (default: the scene's chains or workUnits, or 16).
    #[arg(long)]
    chains: Option<usize>,
    /// Metropolis: bootstrap samples for the normalisation and the chains'
    /// starts (default: the scene's luminanceSamples, or 100000).
    #[arg(long)]
    bootstrap: Option<usize>,
    /// Veach's MLT: relative frequencies of the bidirectional, lens, caustic
    /// and multi-chain mutations, as four numbers `b,l,c,m` (default: the
    /// scene's switches, or 1,1,1,1).
    #[arg(long, value_parser = parse_mix)]
    mutations: Option<[f64; 4]>,
    /// Veach's MLT: samples per pixel of a separate direct-lighting pass
    /// (default: the scene's directSamples; 0: none).
    #[arg(long)]
    direct_samples: Option<u32>,
    /// Film width and height for the built-in scene.
    #[arg(long, default_value_t = 512)]
    size: u32,
    /// Render part K of N (K from 0) and write it, with what a merge needs,
    /// to the output (see `aether merge`): a share of every pixel's
    /// samples, or of the Metropolis chains.
    #[arg(long)]
    shard: Option<Shard>,
    /// Film width for a scene file (the height keeps its aspect ratio; the
    /// crop window becomes the whole film).
    #[arg(long)]
    width: Option<u32>,
}

fn parse_mix(s: &str) -> Result<[f64; 4], String> {
    let parts: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>().map_err(|e| format!("'{p}': {e}")))
        .collect::<Result<_, _>>()?;
    let mix: [f64; 4] = parts
        .try_into()
        .map_err(|_| format!("'{s}' is not four numbers b,l,c,m"))?;
    if mix.iter().any(|w| !(w.is_finite() && *w >= 0.0)) || mix[0] <= 0.0 {
        return Err(format!(
            "'{s}': frequencies must be finite and ≥ 0, and the bidirectional mutation's positive (the perturbations alone do not reach every path)"
        ));
    }
    Ok(mix)
}

fn parse_param(s: &str) -> Result<(String, String), String> {
    s.split_once('=')
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .ok_or_else(|| format!("'{s}' is not name=value"))
}

fn run(args: RenderArgs) -> Result<Outcome, String> {
    let params: HashMap<String, String> = args.define.iter().cloned().collect();
    let outputs = OutputFiles::for_name(&args.output).map_err(|e| e.to_string())?;
    if args.threads == Some(0) {
        return Err("--threads must be at least 1 (leave it out for all cores)".to_string());
    }
    let scene = match &args.scene {
        Some(path) => Scene::load(path, &params).map_err(|e| e.to_string())?,
        None => {
            let size = u64::from(args.size);
            Film::check_size(size, size).map_err(|e| format!("--size {}: {e}", args.size))?;
            cornell_box(args.size.max(1), args.size.max(1), 16)
        }
    };
    for w in &scene.warnings {
        eprintln!("{w}");
    }
    // What goes wrong past loading names the scene it happened to.
    let name = args
        .scene
        .as_ref()
        .map_or("the built-in Cornell box".to_string(), |p| {
            p.display().to_string()
        });
    render_scene(&args, scene, &outputs).map_err(|e| match e.starts_with(&name) {
        true => e,
        false => format!("{name}: {e}"),
    })
}

/// Renders a loaded scene with the command line's settings.
fn render_scene(
    args: &RenderArgs,
    mut scene: Scene,
    outputs: &OutputFiles,
) -> Result<Outcome, String> {
    if let Some(spp) = args.spp {
        if spp == 0 {
            return Err("--spp must be positive".to_string());
        }
        scene.film.spp = spp;
    }
    if let Some(width) = args.width {
        if width == 0 {
            return Err("--width must be positive".to_string());
        }
        scene
            .film
            .scale_to_width(width)
            .map_err(|e| format!("--width {width}: {e}"))?;
    }
    if let Some(d) = args.max_depth {
        scene.integrator.max_depth = d;
    }
    let wanted = args.integrator.map_or(scene.integrator.name.clone(), |i| {
        format!("{i:?}").to_lowercase()
    });
    scene.integrator.name = wanted;
    outputs.check_writable()?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    // Ctrl-C, SIGTERM (a batch system's time limit) and SIGHUP stop the
    // render between samples and write what it holds; a second one quits.
    ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::Relaxed) {
            eprintln!("\nstopped again: quitting without writing");
            std::process::exit(130);
        }
        eprintln!("\nstopping: writing the image at the samples taken (again to quit at once)");
    })
    .map_err(|e| format!("cannot catch Ctrl-C: {e}"))?;
    let time_limit = match args.time_limit {
        Some(t) if t.is_finite() && t > 0.0 => Some(Duration::from_secs_f64(t)),
        Some(t) => {
            return Err(format!(
                "--time-limit must be a positive number of seconds, not {t}"
            ));
        }
        None => None,
    };
    let settings = Settings {
        spp: scene.film.spp,
        seed: args.seed,
        first_sample: 0,
        shard: args.shard.unwrap_or(Shard::WHOLE),
        time_limit,
        threads: args.threads,
        progress: true,
    };
    if scene.integrator.name == "gpt" {
        run_gradients(&scene, &settings, &stop, outputs, args.exposure)?;
        return Ok(stopped(&stop));
    }
    let scene_mlt = MltSettings::for_scene(&scene);
    let mlt = MltSettings {
        large_step: args.large_step.unwrap_or(scene_mlt.large_step),
        chains: args.chains.unwrap_or(scene_mlt.chains),
        bootstrap: args.bootstrap.unwrap_or(scene_mlt.bootstrap),
        mutations: args.mutations.unwrap_or(scene_mlt.mutations),
        direct_samples: args.direct_samples.unwrap_or(scene_mlt.direct_samples),
        ..scene_mlt
    };
    if !(0.0..=1.0).contains(&mlt.large_step) || mlt.chains == 0 || mlt.bootstrap == 0 {
        return Err(
            "--large-step must be in [0, 1], --chains and --bootstrap positive".to_string(),
        );
    }
    let described = format!("spp={} {mlt:?}", scene.film.spp);
    let r = match &args.techniques {
        Some(_) if args.shard.is_some() => {
            return Err("--techniques and --shard cannot be combined".to_string());
        }
        Some(dir) => {
            let bdpt = match scene.integrator.name.as_str() {
                "bdpt" | "tridir" => Bdpt::for_scene(&scene)?,
                other => return Err(format!("--techniques needs -i bdpt or tridir, not {other}")),
            };
            let bdpt = bdpt.with_technique_images(args.technique_vertices);
            let r = render_with(&scene, &bdpt, &settings, &stop)?;
            if let Some(images) = bdpt.technique_images() {
                images.write(dir, r.samples, scene.film.spp, scene.aperture().is_some())?;
            }
            r
        }
        None if Variant::named(&scene.integrator.name).is_some() => {
            render_mlt(&scene, mlt, &settings, &stop)?
        }
        None => render(&scene, &settings, &stop)?,
    };
    let image = r.film.image();
    let (w, h) = (scene.film.width, scene.film.height);
    let pixels = r.film.rendered_pixels().max(1) as u64;
    let metropolis = Variant::named(&scene.integrator.name).is_some();
    let (exr, png) = (&outputs.exr, &outputs.png);
    if let Some(shard) = args.shard {
        let mut partial = r.partial;
        put_render(&mut partial, &scene, &described, args.seed);
        write_part(exr, shard, &partial, &image)?;
    } else if metropolis {
        // Chains splat everywhere: the file says mutations per pixel.
        let spp = u32::try_from(r.samples / pixels).unwrap_or(u32::MAX);
        write_exr(exr, w, h, &image, spp, r.seconds)?;
    } else {
        write_exr_with_counts(exr, w, h, &image, r.film.counts(), r.seconds)?;
    }
    write_png(png, w, h, &image, args.exposure)?;
    if !r.complete {
        eprintln!(
            "stopped early: {} of {} pixels rendered, {:.1} samples per pixel on average (of {} asked)",
            r.film.rendered_pixels(),
            w as usize * h as usize,
            r.samples as f64 / pixels as f64,
            scene.film.spp
        );
        if r.samples == 0 && metropolis {
            eprintln!(
                "the time limit ran out before the chains started: the bootstrap took it (see --bootstrap)"
            );
        }
    }
    if r.film.dropped() > 0 {
        eprintln!("{} NaN or infinite samples were dropped", r.film.dropped());
    }
    println!(
        "{} and {}: {:.2} s, {:.0} samples/s, {:.2} Mrays/s",
        exr.display(),
        png.display(),
        r.seconds,
        r.samples as f64 / r.seconds,
        r.rays as f64 / r.seconds / 1e6,
    );
    Ok(stopped(&stop))
}

/// How a render that wrote its images ends: stopped by a signal, or not.
fn stopped(stop: &AtomicBool) -> Outcome {
    if stop.load(Ordering::Relaxed) {
        Outcome::Interrupted
    } else {
        Outcome::Finished
    }
}

/// How a command that did not fail ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    Finished,
    /// Stopped by Ctrl-C or SIGTERM, after writing what it had: the exit
    /// status says so, so that a batch system does not take it for done.
    Interrupted,
}

/// Gradient-domain path tracing: the reconstruction to `output`, and the
/// primal image and the gradients beside it (`-primal`, `-dx`, `-dy`).
fn run_gradients(
    scene: &Scene,
    settings: &Settings,
    stop: &AtomicBool,
    outputs: &OutputFiles,
    exposure: f32,
) -> Result<(), String> {
    let output = outputs.exr.as_path();
    let tracer = GradientPathTracer::new(scene)?;
    let g = render_gradients(scene, &tracer, settings, stop)?;
    if settings.shard != Shard::WHOLE {
        let mut partial = g.partial.clone();
        put_render(
            &mut partial,
            scene,
            &format!("spp={}", settings.spp),
            settings.seed,
        );
        return write_part(&outputs.exr, settings.shard, &partial, &g.primal);
    }
    let image = g.reconstruct(&scene.integrator.gradient);
    let rendered = g.rendered.iter().filter(|&&r| r).count();
    // Cut short, every rendered pixel holds what time allowed.
    let spp = u32::try_from(g.samples / rendered.max(1) as u64).unwrap_or(u32::MAX);
    let (w, h) = (g.width, g.height);
    if !g.complete {
        eprintln!(
            "stopped early: {rendered} of {} pixels rendered, {spp} samples per pixel (of {} asked)",
            w as usize * h as usize,
            settings.spp
        );
    }
    let beside = |suffix: &str| {
        let stem = output
            .file_stem()
            .map_or("out".into(), |s| s.to_string_lossy());
        output.with_file_name(format!("{stem}-{suffix}.exr"))
    };
    for (path, pixels) in [
        (output.to_path_buf(), &image),
        (beside("primal"), &g.primal),
        (beside("dx"), &g.dx),
        (beside("dy"), &g.dy),
    ] {
        write_exr(&path, w, h, pixels, spp, g.seconds)?;
        // Gradients are signed: their previews show magnitudes.
        let preview: Vec<[f32; 3]> = pixels.iter().map(|c| c.map(f32::abs)).collect();
        write_png(&path.with_extension("png"), w, h, &preview, exposure)?;
    }
    if g.dropped > 0 {
        eprintln!("{} NaN or infinite samples were dropped", g.dropped);
    }
    println!(
        "{} (and -primal, -dx, -dy): {:.2} s, {:.0} samples/s, {:.2} Mrays/s",
        output.display(),
        g.seconds,
        g.samples as f64 / g.seconds,
        g.rays as f64 / g.seconds / 1e6,
    );
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => run(*args),
        Command::Compare { reference, images } => {
            compare(&reference, &images).map(|()| Outcome::Finished)
        }
        Command::Merge {
            output,
            parts,
            partial,
            force,
            exposure,
        } => merge(&output, &parts, partial, force, exposure).map(|()| Outcome::Finished),
    };
    match result {
        Ok(Outcome::Finished) => ExitCode::SUCCESS,
        Ok(Outcome::Interrupted) => ExitCode::from(130),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
