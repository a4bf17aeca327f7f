//! Gradient-domain path tracing (Lehtinen et al. 2013, Kettunen et al.
//! 2015): every path of a pixel is shifted into its four neighbours, and
//! each pair of adjacent pixels gets both its difference and a second
//! estimate of each pixel from the pair.
//!
//! The shift replays the base path's uniforms in the neighbour pixel (the
//! camera ray moves by one pixel, then every step samples again from the
//! same uniforms) until the first pair of rough vertices, where the offset
//! reconnects to the base path and copies it from there. Its Jacobian is a
//! ratio of the language's conditional densities of the replayed steps
//! ([`replay_jacobian`](aether_core::replay_jacobian)), and the MIS weights between the base path's
//! techniques and those of the neighbour shifted back come from the same
//! densities ([`weight_of_shift`]). No density is written here.
//!
//! For a base path x̄ of pixel i sampled by technique t with density
//! p_t(x̄), and its offset ȳ in neighbour j with Jacobian J, the pair adds
//! w·f(x̄)/p_t(x̄) to pixel i's estimate and w·f(ȳ)·J/p_t(x̄) to pixel j's,
//! where w weighs t against every technique of both pixels. Summed with the
//! paths of j shifted into i, the two are unbiased estimates of both
//! pixels, so their difference estimates the gradient, and the mean over a
//! pixel's neighbours estimates the pixel (the primal image).

use std::sync::Mutex;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use aether_core::{
    DensityCache, DynStrategy, Heuristic, Pcg32, RandomSequence, StrategyRef, densities_of_split,
    weight_of_shift,
};
use aether_strategies::bsdf::Transport;
use aether_strategies::camera::{Camera, CameraDirection};
use aether_strategies::integrand::{Integrand, visible};
use aether_strategies::lights::Lights;
use aether_strategies::scattering::{BsdfSampling, Roulette};
use aether_strategies::scene::{GradientSettings, Scene};
use aether_strategies::subpath::{End, Subpath};
use aether_strategies::vertex::SceneVertex;
use glam::DVec3;

use crate::estimator::path_limits;
use crate::film::Film;
use crate::film::is_valid;
use crate::path::techniques;
use crate::poisson::{Norm, reconstruct};
use crate::render::{PixelSamples, Rendered, Settings, Tile, render_tiles, repeat_passes};
use crate::rounds::render_rounds;
use crate::shard::Partial;
use crate::shift::{Shift, Shifted, once};

thread_local! {
    /// Density factors of one sample's base and offset paths: the offsets
    /// copy the base's vertices after reconnecting, and every event
    /// re-weighs the same prefix, so each factor is evaluated once.
    static DENSITIES: std::cell::RefCell<DensityCache> = std::cell::RefCell::new(DensityCache::new());
}

/// The four neighbours of a pixel, in the order of [`PairSums`]: left,
/// right, up, down. Directions 2k and 2k + 1 are opposite.
pub const NEIGHBOURS: [[i64; 2]; 4] = [[-1, 0], [1, 0], [0, -1], [0, 1]];

/// One pixel's estimates from its base paths, per neighbour: `base[d]`
/// estimates this pixel and `offset[d]` the neighbour in direction `d`,
/// both as part of the pair of the two pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PairSums {
    /// The base paths' MIS-weighted estimates of this pixel.
    pub base: [DVec3; 4],
    /// Their offset paths' MIS-weighted estimates of the neighbour.
    pub offset: [DVec3; 4],
}

impl PairSums {
    fn add(&mut self, other: &PairSums) {
        for d in 0..4 {
            self.base[d] += other.base[d];
            self.offset[d] += other.offset[d];
        }
    }

    fn is_valid(&self) -> bool {
        self.base
            .iter()
            .chain(&self.offset)
            .all(|c| is_valid(c.as_vec3().to_array()))
    }
}

/// A path tracer with next-event estimation whose every path is shifted
/// into the four neighbouring pixels.
#[derive(Debug)]
pub struct GradientPathTracer<'s> {
    scene: &'s Scene,
    camera: Camera,
    lights: Option<Lights<'s>>,
    max_depth: usize,
    roulette: Roulette,
    heuristic: Heuristic,
    shift: Shift<'s>,
}

impl<'s> GradientPathTracer<'s> {
    /// The tracer of `scene`, with its integrator's depth limits, roughness
    /// threshold, and the power heuristic.
    ///
    /// # Errors
    /// If the camera cannot be built.
    pub fn new(scene: &'s Scene) -> Result<Self, String> {
        let (max_vertices, roulette) = path_limits(scene);
        Ok(GradientPathTracer {
            scene,
            camera: Camera::new(scene)?,
            lights: Lights::new(scene),
            max_depth: max_vertices.saturating_sub(1),
            roulette,
            heuristic: Heuristic::POWER,
            shift: Shift::new(scene, scene.integrator.gradient.roughness_threshold),
        })
    }

    /// The neighbour of `pixel` in direction `d` of [`NEIGHBOURS`], if it is
    /// in the crop window.
    #[must_use]
    pub fn neighbour(&self, pixel: [u32; 2], d: usize) -> Option<[u32; 2]> {
        let [cx, cy, cw, ch] = self.scene.film.crop.map(i64::from);
        let x = i64::from(pixel[0]) + NEIGHBOURS[d][0];
        let y = i64::from(pixel[1]) + NEIGHBOURS[d][1];
        let inside = (cx..cx + cw).contains(&x) && (cy..cy + ch).contains(&y);
        inside.then_some([x as u32, y as u32])
    }

    /// One base path of `pixel` and its shifts into the neighbours.
    pub fn sample(&self, pixel: [u32; 2], rng: &mut Pcg32) -> PairSums {
        let mut out = PairSums::default();
        let Some(lights) = &self.lights else {
            return out;
        };
        let scene = self.scene;
        let neighbours: [Option<[u32; 2]>; 4] = std::array::from_fn(|d| self.neighbour(pixel, d));
        let lens = self.camera.position();
        // Index 0: this pixel; 1 + d: the neighbour in direction d.
        let looks: [CameraDirection<'_>; 5] = std::array::from_fn(|k| {
            let p = if k == 0 { None } else { neighbours[k - 1] };
            self.camera.direction(scene, p.unwrap_or(pixel))
        });
        let bsdf = BsdfSampling::new(scene, Transport::Radiance, self.roulette);
        let direct = lights.direct();
        let f = Integrand::new(scene, &self.camera, lights);
        let cameras: [[StrategyRef<'_, SceneVertex>; 3]; 5] = std::array::from_fn(|k| {
            [&lens as &dyn DynStrategy<_>, &looks[k], &bsdf].map(StrategyRef::One)
        });
        let by_light = [(StrategyRef::One(&direct as &dyn DynStrategy<_>), false)];

        DENSITIES.with_borrow_mut(DensityCache::clear);
        let start = rng.clone();
        let mut base = RandomSequence::new();
        if !base.append(&lens).append_sample(&looks[0], rng) {
            return out;
        }
        let importance = f.importance(pixel, base.vertices());
        let mut eye = Subpath::new(f, End::Camera);
        eye.extend(base.vertices());
        let mut offsets = self
            .shift
            .start(f, &lens, &looks[1..], &neighbours, &base, &start);
        // Adds one base path (technique `own`, value `fx`) and the offsets'
        // paths of the same length, with their values.
        let mut contribute = |own: usize,
                              fx: DVec3,
                              base: &RandomSequence<'_, SceneVertex>,
                              offsets: &[Shifted<'_, '_>; 4]| {
            let n = base.len();
            let (splits, count) = techniques(n, &by_light);
            let splits = &splits[..count];
            let dx = DENSITIES
                .with_borrow_mut(|c| densities_of_split(base, &cameras[0], &[], splits, Some(c)));
            let px = dx[own].value();
            // Long paths through near-specular surfaces can overflow f or
            // p: such a path contributes nothing.
            if !(px > 0.0 && px.is_finite() && fx.is_finite()) {
                return;
            }
            for d in 0..4 {
                let Some(_) = neighbours[d] else { continue };
                let (fy, w, jacobian) = match offsets[d] {
                    Some((o, fy, jacobian))
                        if fy.is_finite() && (fx != DVec3::ZERO || fy != DVec3::ZERO) =>
                    {
                        // Far enough past the reconnection, the offset's
                        // densities are the base's times one ratio, which
                        // the first such event measures.
                        let settled = o.joined_at.is_some_and(|k| n >= k + 3 + own);
                        let w = match o.ratio.get().filter(|_| settled) {
                            Some(r) => {
                                weight_of_shift(&dx, Some((&dx, jacobian * r)), own, self.heuristic)
                            }
                            None => {
                                let dy = DENSITIES.with_borrow_mut(|c| {
                                    densities_of_split(
                                        &o.path,
                                        &cameras[1 + d],
                                        &[],
                                        splits,
                                        Some(c),
                                    )
                                });
                                if settled {
                                    o.ratio.set(Some(dx[own].ratio_to(dy[own])));
                                }
                                weight_of_shift(&dx, Some((&dy, jacobian)), own, self.heuristic)
                            }
                        };
                        (fy, w, jacobian)
                    }
                    _ if fx != DVec3::ZERO => (
                        DVec3::ZERO,
                        weight_of_shift(&dx, None, own, self.heuristic),
                        0.0,
                    ),
                    _ => continue,
                };
                out.base[d] += fx * (w / px);
                out.offset[d] += fy * (w * jacobian / px);
            }
        };
        loop {
            let n = base.len();
            if n >= 2 {
                contribute(0, eye.emitted(n) * importance, &base, &offsets.emitted(n));
            }
            if n <= self.max_depth && eye.connectible(n - 1) {
                let replay = rng.clone();
                if base.append_sample(&direct, rng) {
                    let lamp = base.vertices()[n];
                    // The edge to the lamp is the base's for every offset
                    // that reconnected before it: one shadow ray for all.
                    let clear = once(|| visible(scene, &base.vertices()[n - 1], &lamp));
                    let mut lit = eye.connect_lamp_unoccluded(n, &lamp);
                    if lit != DVec3::ZERO && !clear() {
                        lit = DVec3::ZERO;
                    }
                    let shifted = offsets.connect_lamp(&base, &direct, &replay, &clear);
                    contribute(1, lit * importance, &base, &shifted);
                }
                base.truncate(n);
                offsets.truncate(n);
            }
            if n > self.max_depth {
                break;
            }
            let replay = rng.clone();
            if !base.append_sample(&bsdf, rng) {
                break;
            }
            eye.push(base.vertices()[n]);
            offsets.advance(&base, &eye, &bsdf, &replay);
        }
        out
    }
}

/// What a gradient-domain render produced: the primal image and the
/// horizontal and vertical gradients, row by row.
#[derive(Debug)]
pub struct Gradients {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Each pixel's estimate: the mean of its pairs' estimates.
    pub primal: Vec<[f32; 3]>,
    /// I(x + 1, y) − I(x, y) (zero in the last column and outside the crop).
    pub dx: Vec<[f32; 3]>,
    /// I(x, y + 1) − I(x, y) (zero in the last row and outside the crop).
    pub dy: Vec<[f32; 3]>,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Base paths traced.
    pub samples: u64,
    /// Rays cast.
    pub rays: u64,
    /// Seconds spent casting them, summed over threads, when rays are timed.
    pub ray_seconds: f64,
    /// Samples dropped as NaN, infinite or negative.
    pub dropped: u64,
    /// False if the time limit or a stop request cut the render short.
    pub complete: bool,
    /// Which pixels were rendered.
    pub rendered: Vec<bool>,
    /// What a merge with the render's other parts needs: each pixel's
    /// pair sums and count (of the first pass, for passes).
    pub partial: Partial,
}

impl Gradients {
    /// Adds another render's images and counts to these.
    fn accumulate(&mut self, other: &Gradients) {
        let images = [
            (&mut self.primal, &other.primal),
            (&mut self.dx, &other.dx),
            (&mut self.dy, &other.dy),
        ];
        for (mine, theirs) in images {
            for (a, b) in mine.iter_mut().zip(theirs) {
                *a = [0, 1, 2].map(|k| a[k] + b[k]);
            }
        }
        for (a, b) in self.rendered.iter_mut().zip(&other.rendered) {
            *a |= b;
        }
        self.samples += other.samples;
        self.rays += other.rays;
        self.ray_seconds += other.ray_seconds;
        self.dropped += other.dropped;
        self.complete &= other.complete;
    }

    /// The screened Poisson reconstruction with the scene's α and norm.
    #[must_use]
    pub fn reconstruct(&self, settings: &GradientSettings) -> Vec<[f32; 3]> {
        let norm = if settings.l1 { Norm::L1 } else { Norm::L2 };
        let (w, h) = (self.width, self.height);
        reconstruct(w, h, &self.primal, &self.dx, &self.dy, settings.alpha, norm)
    }

    /// A render result whose film holds `image` at the rendered pixels.
    #[must_use]
    pub fn rendered(&self, image: &[[f32; 3]]) -> Rendered {
        let image: Vec<[f64; 3]> = image.iter().map(|c| c.map(f64::from)).collect();
        let mut film = Film::from_image(self.width, self.height, &image, |i| self.rendered[i]);
        film.count_dropped(self.dropped);
        Rendered {
            film,
            seconds: self.seconds,
            samples: self.samples,
            rays: self.rays,
            ray_seconds: self.ray_seconds,
            complete: self.complete,
            partial: self.partial.clone(),
        }
    }
}

/// Renders the primal image and the gradients of `scene` with `tracer`.
///
/// # Errors
/// If the crop window has a single pixel (no pair to shift across) or the
/// worker threads cannot start.
pub fn render_gradients(
    scene: &Scene,
    tracer: &GradientPathTracer<'_>,
    settings: &Settings,
    stop: &AtomicBool,
) -> Result<Gradients, String> {
    let (w, h) = (scene.film.width, scene.film.height);
    let [_, _, cw, ch] = scene.film.crop;
    if u64::from(cw) * u64::from(ch) < 2 {
        return Err("gradient-domain rendering needs at least two pixels".to_string());
    }
    let mut sums: Vec<Option<PairSums>> = vec![None; w as usize * h as usize];
    let dropped = Mutex::new(0u64);
    // A pair's estimates need both pixels at the same count: a round that
    // time cuts short is left out, unless it is the first.
    let pixels = u64::from(cw) * u64::from(ch);
    let rounds = render_rounds(settings, pixels, |index, this, bar| {
        let this_round: Mutex<Vec<Option<PairSums>>> =
            Mutex::new(vec![None; w as usize * h as usize]);
        // A pixel cut short by a stop keeps nothing of this round.
        let pixel = |p: [u32; 2], samples: PixelSamples<'_>| {
            let (mut sum, mut lost, asked) = (PairSums::default(), 0u64, samples.asked());
            let mut taken = 0;
            for mut rng in samples {
                let s = tracer.sample(p, &mut rng);
                taken += 1;
                if s.is_valid() {
                    sum.add(&s);
                } else {
                    lost += 1;
                }
            }
            (taken == asked).then_some((sum, lost))
        };
        let store = |tile: Tile<Option<(PairSums, u64)>>| {
            let mut sums = this_round
                .lock()
                .expect("no thread panics while holding the sums");
            let mut lost = 0;
            for ([x, y], (s, l)) in tile.into_iter().filter_map(|(p, r)| Some((p, r?))) {
                sums[(y * w + x) as usize] = Some(s);
                lost += l;
            }
            *dropped.lock().expect("no thread panics while counting") += lost;
        };
        let run = render_tiles(scene, this, stop, bar, pixel, store)?;
        if run.complete || index == 0 {
            let this_round = this_round.into_inner().expect("no thread panicked");
            for (total, s) in sums.iter_mut().zip(this_round) {
                match (total.as_mut(), s) {
                    (Some(t), Some(s)) => t.add(&s),
                    (None, s) => *total = s,
                    (Some(_), None) => {}
                }
            }
        }
        Ok(run)
    })?;
    let done = rounds.spp;
    let [primal, dx, dy] = pair_images(w, h, &sums, done);
    let mut partial = Partial::new(w, h);
    for d in 0..4 {
        let base: Vec<[f64; 3]> = sums
            .iter()
            .map(|s| s.as_ref().map_or([0.0; 3], |s| s.base[d].to_array()))
            .collect();
        let offset: Vec<[f64; 3]> = sums
            .iter()
            .map(|s| s.as_ref().map_or([0.0; 3], |s| s.offset[d].to_array()))
            .collect();
        partial.put_rgb(&format!("base{d}"), &base);
        partial.put_rgb(&format!("offset{d}"), &offset);
    }
    let counts = sums
        .iter()
        .map(|s| if s.is_some() { f64::from(done) } else { 0.0 });
    partial.planes.insert("samples".into(), counts.collect());
    let gradient = &scene.integrator.gradient;
    partial
        .same
        .insert("gpt.l1".into(), gradient.l1.to_string());
    partial
        .same
        .insert("gpt.alpha".into(), gradient.alpha.to_string());
    let dropped = dropped.into_inner().expect("no thread panicked");
    partial.totals.insert("dropped".into(), dropped as f64);
    Ok(Gradients {
        width: w,
        height: h,
        primal,
        dx,
        dy,
        seconds: rounds.seconds,
        samples: sums.iter().flatten().count() as u64 * u64::from(done),
        rays: rounds.rays,
        ray_seconds: rounds.ray_seconds,
        dropped,
        complete: rounds.complete,
        rendered: sums.iter().map(Option::is_some).collect(),
        partial,
    })
}

/// The primal image and the two gradient images of a `w` × `h` film from
/// each pixel's pair sums over `done` samples (`None`: not rendered): each
/// pair of neighbours estimates both pixels and their difference.
#[must_use]
pub fn pair_images(w: u32, h: u32, sums: &[Option<PairSums>], done: u32) -> [Vec<[f32; 3]>; 3] {
    let spp = f64::from(done.max(1));
    let at = |x: i64, y: i64| -> Option<&PairSums> {
        if x < 0 || y < 0 || x >= i64::from(w) || y >= i64::from(h) {
            return None;
        }
        sums[(y * i64::from(w) + x) as usize].as_ref()
    };
    let mut images = [(); 3].map(|()| vec![[0.0f32; 3]; sums.len()]);
    let rgb = |v: DVec3| (v / spp).to_array().map(crate::film::saturate);
    for y in 0..i64::from(h) {
        for x in 0..i64::from(w) {
            let Some(own) = at(x, y) else { continue };
            let i = (y * i64::from(w) + x) as usize;
            let (mut primal, mut pairs) = (DVec3::ZERO, 0.0);
            for (d, [ox, oy]) in NEIGHBOURS.iter().enumerate() {
                let Some(other) = at(x + ox, y + oy) else {
                    continue;
                };
                // The pair's estimate of this pixel: this pixel's base paths
                // and the neighbour's offsets into it.
                primal += own.base[d] + other.offset[d ^ 1];
                pairs += 1.0;
                // Right and down: the pair's estimate of the difference.
                if d == 1 || d == 3 {
                    let difference =
                        (own.offset[d] + other.base[d ^ 1]) - (own.base[d] + other.offset[d ^ 1]);
                    images[if d == 1 { 1 } else { 2 }][i] = rgb(difference);
                }
            }
            if pairs > 0.0 {
                images[0][i] = rgb(primal / pairs);
            }
        }
    }
    images
}

/// Renders whole passes of gradients until `budget` has passed, as
/// [`render_passes`](crate::render::render_passes) does for images, and
/// averages them; returns the average and the number of passes.
///
/// # Errors
/// As [`render_gradients`].
pub fn render_gradient_passes(
    scene: &Scene,
    tracer: &GradientPathTracer<'_>,
    settings: &Settings,
    budget: Duration,
    stop: &AtomicBool,
) -> Result<(Gradients, u32), String> {
    let mut total: Option<Gradients> = None;
    let (passes, seconds) = repeat_passes(settings, budget, stop, |pass| {
        let g = render_gradients(scene, tracer, pass, stop)?;
        match &mut total {
            Some(t) => t.accumulate(&g),
            None => total = Some(g),
        }
        Ok(())
    })?;
    let mut g = total.ok_or("no pass was rendered")?;
    let n = passes as f32;
    for image in [&mut g.primal, &mut g.dx, &mut g.dy] {
        for c in image.iter_mut() {
            *c = c.map(|v| v / n);
        }
    }
    g.seconds = seconds;
    Ok((g, passes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cornell::cornell_box;

    #[test]
    fn a_time_limit_gives_every_pixel_the_same_count() {
        let scene = cornell_box(16, 16, 1);
        let tracer = GradientPathTracer::new(&scene).unwrap();
        let settings = Settings {
            time_limit: Some(Duration::from_millis(300)),
            ..Settings::new(u32::MAX, 1)
        };
        let g = render_gradients(&scene, &tracer, &settings, &AtomicBool::new(false)).unwrap();
        assert!(!g.complete);
        assert!(g.rendered.iter().all(|&r| r));
        // Whole rounds only: a pair's two pixels have the same count.
        assert_eq!(g.samples % (16 * 16), 0);
        assert!(g.samples >= 2 * 16 * 16, "{} samples", g.samples);
        assert!(g.primal.iter().flatten().all(|v| v.is_finite()));
    }
}
