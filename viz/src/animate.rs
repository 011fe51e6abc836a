//! The robot, moving: the plate and the arm of a [`Trace`] drawn frame by frame with plotters into
//! an animated GIF (encoded with the `gif` crate: one fixed palette, only the changed rectangle
//! of each frame) or into a directory of numbered PNG frames (for a video encoder).
//!
//! Geometry and conventions are those of `docs/model.md`: world frame with the origin at the
//! plate's left edge lying flat, `x` to the right, `y` up (m); `alpha` is the plate's tilt
//! (counter-clockwise positive, `> 0` over the left edge, `< 0` over the right edge), `beta` the
//! arm angle relative to the plate (`pi/2` upright). The plate is the segment of length `2 f` on
//! the ground, rotated by `alpha` about the pivot of its mode; the arm of length `l` is mounted at
//! the plate's centre.
//!
//! Each frame shows the ground, the plate (drawn as a thin slab above its contact line), the
//! arm with its tip mass, the active pivot edge (an orange wedge under it), the time, the mode and
//! the angles, and a timeline with the landings. A landing (tilted to flat) is flashed: for
//! [`FLASH`] s of playback the plate turns red and a red ring marks the edge that strikes the
//! ground.
//!
//! Frames are drawn and encoded one at a time: memory does not grow with the length of the clip.

use crate::plot::{register_fonts, Trace};
use anyhow::{anyhow, bail, Context as _, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use tilting_plant::kinematics::{pivot, point_masses};
use tilting_plant::{Mode, Params, State};
use tilting_sim::closed_loop::Sample;

/// Playback time (s, wall clock) during which a landing is flashed; at least one frame.
pub const FLASH: f64 = 0.12;

/// Largest frame rate (1/s): GIF delays are whole centiseconds, and viewers replace delays
/// below 2 cs by 10 cs.
pub const MAX_FPS: f64 = 50.0;

/// Where the frames go.
#[derive(Debug, Clone, Copy)]
pub enum Output<'a> {
    /// One animated GIF file, looping forever.
    Gif(&'a Path),
    /// A directory (which must exist) of PNG frames `frame_000000.png`, `frame_000001.png`, ...,
    /// shown at [`Timeline::fps`]; e.g. `ffmpeg -framerate FPS -i DIR/frame_%06d.png out.mp4`.
    Frames(&'a Path),
}

/// How to animate a trace.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// Requested frame rate (frames per second of playback), in `(0, MAX_FPS]`. GIF delays are
    /// whole centiseconds: the rate used is `100 / round(100 / fps)` (25 and 50 are exact).
    pub fps: f64,
    /// Playback speed: plant seconds per second of playback (`1` real time, `0.25` slow motion).
    pub speed: f64,
    /// Frame size (px).
    pub size: (u32, u32),
    /// First plant time shown (s); `None`: the first sample.
    pub start: Option<f64>,
    /// Last plant time shown (s); `None`: the trace's end.
    pub end: Option<f64>,
    /// The tilt drawn this many times larger (display only, stated in the frame; `1` is to
    /// scale, the default; the pivot stays on the ground).
    pub tilt_exaggeration: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            fps: 25.0,
            speed: 1.0,
            size: (640, 480),
            start: None,
            end: None,
            tilt_exaggeration: 1.0,
        }
    }
}

impl Options {
    /// Checks every option, the error naming it by its `tilting animate` flag and its range:
    /// `fps` in `(0, MAX_FPS]`, `speed` > 0, `start` and `end` finite with `end` after `start`,
    /// `size` from 160 x 120 to 4096 x 4096 px, `tilt_exaggeration` in `[1, 100]`.
    pub fn validate(&self) -> Result<()> {
        let finite = |name: &str, v: f64, ok: bool, allowed: &str| {
            if v.is_finite() && ok {
                Ok(())
            } else {
                Err(anyhow!("invalid `--{name}` = {v}: must be {allowed}"))
            }
        };
        let fps = self.fps;
        finite(
            "fps",
            fps,
            fps > 0.0 && fps <= MAX_FPS,
            &format!("in (0, {MAX_FPS}]"),
        )?;
        finite("speed", self.speed, self.speed > 0.0, "a positive number")?;
        for (name, v) in [("start", self.start), ("end", self.end)] {
            if let Some(v) = v {
                finite(name, v, true, "a number of seconds")?;
            }
        }
        let (w, h) = self.size;
        if !((160..=4096).contains(&w) && (120..=4096).contains(&h)) {
            bail!("invalid `--size` = {w}x{h}: must be from 160x120 to 4096x4096 px");
        }
        if let (Some(a), Some(b)) = (self.start, self.end) {
            if b <= a {
                bail!("invalid `--end` = {b}: must be after `--start` = {a}");
            }
        }
        let k = self.tilt_exaggeration;
        finite(
            "tilt-exaggeration",
            k,
            (1.0..=100.0).contains(&k),
            "from 1 (to scale) to 100",
        )
    }
}

/// The frame times of an animation: frame `i` shows plant time `t0 + i dt`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timeline {
    /// Plant time of the first frame (s).
    pub t0: f64,
    /// Plant time of the last frame shown at most (s).
    pub t1: f64,
    /// Plant time between frames (s): `speed * delay_cs / 100`.
    pub dt: f64,
    /// Number of frames.
    pub frames: usize,
    /// Delay between frames in the GIF (centiseconds).
    pub delay_cs: u32,
}

impl Timeline {
    /// The frame rate of playback (1/s), `100 / delay_cs`.
    pub fn fps(&self) -> f64 {
        100.0 / self.delay_cs as f64
    }

    /// Plant time of frame `i` (s).
    pub fn time(&self, i: usize) -> f64 {
        self.t0 + i as f64 * self.dt
    }
}

/// The frame times for `trace` under `opts`: from the start (default: the first sample) to the
/// end (default: [`Trace::end`]), both included when they fall on a frame. Errors name the
/// option that is out of range, or say that the trace has no samples in the window.
pub fn timeline(trace: &Trace, opts: &Options) -> Result<Timeline> {
    opts.validate()?;
    let (Some(first), Some(last)) = (trace.samples.first(), trace.samples.last()) else {
        bail!("the trace has no samples: nothing to animate");
    };
    let t0 = opts.start.unwrap_or(first.t).max(first.t);
    let end = if trace.end.is_finite() {
        trace.end.max(last.t)
    } else {
        last.t
    };
    let t1 = opts.end.unwrap_or(end).min(end);
    if !(t0.is_finite() && t1.is_finite() && t1 >= t0) {
        bail!(
            "the window [{t0}, {t1}] s is empty: the trace runs from {} s to {end} s",
            first.t
        );
    }
    let delay_cs = (100.0 / opts.fps).round().max(2.0) as u32;
    let dt = opts.speed * delay_cs as f64 / 100.0;
    // A relative tolerance keeps the last frame when (t1 - t0) / dt is a whole number.
    let frames = ((t1 - t0) / dt * (1.0 + 1e-12) + 1e-9).floor() as usize + 1;
    Ok(Timeline {
        t0,
        t1,
        dt,
        frames,
        delay_cs,
    })
}

/// The plate and the arm at one instant, in the world frame (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// The plate's left edge (`(0, 0)` when flat or tilted left).
    pub left: [f64; 2],
    /// The plate's right edge (`(2 f, 0)` when flat or tilted right).
    pub right: [f64; 2],
    /// The plate's centre, where the arm is mounted (mass `m_f`).
    pub centre: [f64; 2],
    /// The arm's tip (mass `m_l`).
    pub tip: [f64; 2],
    /// The edge the plate rotates about: the left edge when tilted left, the right edge when
    /// tilted right; `None` when flat (both edges rest on the ground).
    pub pivot: Option<[f64; 2]>,
}

/// The pose for `mode`, plate tilt `alpha` (rad) and arm angle `beta` (rad, relative to the
/// plate), from [`tilting_plant::kinematics`].
pub fn pose(p: &Params, mode: Mode, alpha: f64, beta: f64) -> Pose {
    let q = point_masses(p, mode, &State::new(alpha, beta, 0.0, 0.0));
    let u = [alpha.cos(), alpha.sin()];
    let c = [q.foot.x, q.foot.y];
    Pose {
        left: [c[0] - p.f * u[0], c[1] - p.f * u[1]],
        right: [c[0] + p.f * u[0], c[1] + p.f * u[1]],
        centre: c,
        tip: [q.tip.x, q.tip.y],
        pivot: mode.is_tilted().then(|| {
            let v = pivot(p, mode);
            [v.x, v.y]
        }),
    }
}

/// The mode and `(alpha, beta)` (rad) at plant time `t` (s): linear interpolation between the
/// samples around `t` when both are in the same mode, else the sample before (a mode holds until
/// its event, which the trace records at both sides). Before the first sample: the first; after
/// the last: the last. `None` for no samples.
pub fn state_at(samples: &[Sample], t: f64) -> Option<(Mode, f64, f64)> {
    let i = samples.partition_point(|s| s.t <= t);
    let Some(a) = i.checked_sub(1).and_then(|k| samples.get(k)) else {
        let b = samples.first()?;
        return Some((b.mode, b.x[0], b.x[1]));
    };
    let Some(b) = samples.get(i) else {
        return Some((a.mode, a.x[0], a.x[1]));
    };
    if a.mode != b.mode || b.t <= a.t {
        return Some((a.mode, a.x[0], a.x[1]));
    }
    let w = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
    let lerp = |k: usize| a.x[k] + w * (b.x[k] - a.x[k]);
    Some((a.mode, lerp(0), lerp(1)))
}

/// What [`animate`] wrote.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rendered {
    /// The frame times.
    pub timeline: Timeline,
    /// Frames in which a landing is flashed.
    pub flashed: usize,
}

/// Renders `trace` for the plant `params` into `out`, one frame at a time, calling
/// `progress(done, frames)` after each frame (frames written so far, frames in all). Errors
/// name the output file.
pub fn animate(
    out: Output,
    params: &Params,
    trace: &Trace,
    opts: &Options,
    progress: &dyn Fn(usize, usize),
) -> Result<Rendered> {
    register_fonts()?;
    let tl = timeline(trace, opts)?;
    let scene = Scene::new(params, trace, &tl, opts);
    let mut flashed = 0;
    match out {
        Output::Gif(path) => {
            flashed = write_gif(path, &scene, &tl, opts.size, progress)?;
        }
        Output::Frames(dir) => {
            if !dir.is_dir() {
                bail!("the frame directory {} does not exist", dir.display());
            }
            for i in 0..tl.frames {
                let path = dir.join(format!("frame_{i:06}.png"));
                let root = BitMapBackend::new(&path, opts.size).into_drawing_area();
                flashed += scene.draw(&root, tl.time(i))? as usize;
                root.present()
                    .with_context(|| format!("cannot write {}", path.display()))?;
                progress(i + 1, tl.frames);
            }
        }
    }
    Ok(Rendered {
        timeline: tl,
        flashed,
    })
}

/// The GIF's palette (256 RGB triples): the 6 x 6 x 6 colour cube, levels `0, 51, ..., 255`,
/// index `36 r + 6 g + b`; the last 40 entries are unused (black).
fn cube_palette() -> Vec<u8> {
    let mut palette = Vec::with_capacity(256 * 3);
    for r in 0..6u8 {
        for g in 0..6u8 {
            for b in 0..6u8 {
                palette.extend_from_slice(&[r * 51, g * 51, b * 51]);
            }
        }
    }
    palette.resize(256 * 3, 0);
    palette
}

/// Each RGB pixel of `rgb` to the index of the nearest colour of [`cube_palette`].
fn quantise(rgb: &[u8], idx: &mut [u8]) {
    let level = |v: u8| (v as u16 * 5 + 127) / 255;
    for (k, px) in idx.iter_mut().zip(rgb.chunks_exact(3)) {
        *k = (level(px[0]) * 36 + level(px[1]) * 6 + level(px[2])) as u8;
    }
}

/// Writes the frames of `scene` into the GIF `path`; returns the number of flashed frames.
///
/// One global palette, the 6 x 6 x 6 colour cube (each pixel rounded to the nearest level of
/// 51), so no per-frame quantisation; every frame after the first holds only the rectangle that
/// changed (disposal "keep"), which the viewers compose over the previous frame.
fn write_gif(
    path: &Path,
    scene: &Scene,
    tl: &Timeline,
    size: (u32, u32),
    progress: &dyn Fn(usize, usize),
) -> Result<usize> {
    let (w, h) = (size.0 as usize, size.1 as usize);
    let palette = cube_palette();
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let io = |e: gif::EncodingError| anyhow!("cannot write {}: {e}", path.display());
    let mut enc = gif::Encoder::new(
        std::io::BufWriter::new(file),
        size.0 as u16,
        size.1 as u16,
        &palette,
    )
    .map_err(io)?;
    enc.set_repeat(gif::Repeat::Infinite).map_err(io)?;
    let mut rgb = vec![0u8; w * h * 3];
    let mut idx = vec![0u8; w * h];
    let mut prev: Option<Vec<u8>> = None;
    let mut flashed = 0;
    for i in 0..tl.frames {
        {
            let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
            flashed += scene.draw(&root, tl.time(i))? as usize;
            root.present()?;
        }
        quantise(&rgb, &mut idx);
        // The rectangle [x0, x1) x [y0, y1) that differs from the previous frame.
        let (mut x0, mut y0, mut x1, mut y1) = (0, 0, w, h);
        if let Some(p) = &prev {
            (x0, y0, x1, y1) = (w, h, 0, 0);
            for y in 0..h {
                let (a, b) = (&idx[y * w..(y + 1) * w], &p[y * w..(y + 1) * w]);
                if let Some(first) = a.iter().zip(b).position(|(u, v)| u != v) {
                    let last = w - a
                        .iter()
                        .rev()
                        .zip(b.iter().rev())
                        .position(|(u, v)| u != v)
                        .unwrap_or(0);
                    (x0, x1) = (x0.min(first), x1.max(last));
                    (y0, y1) = (y0.min(y), y + 1);
                }
            }
            if x1 <= x0 {
                // Nothing changed: one pixel, to keep the frame's delay.
                (x0, y0, x1, y1) = (0, 0, 1, 1);
            }
        }
        let mut sub = Vec::with_capacity((x1 - x0) * (y1 - y0));
        for y in y0..y1 {
            sub.extend_from_slice(&idx[y * w + x0..y * w + x1]);
        }
        let frame = gif::Frame {
            left: x0 as u16,
            top: y0 as u16,
            width: (x1 - x0) as u16,
            height: (y1 - y0) as u16,
            buffer: std::borrow::Cow::Owned(sub),
            delay: tl.delay_cs as u16,
            dispose: gif::DisposalMethod::Keep,
            ..gif::Frame::default()
        };
        enc.write_frame(&frame).map_err(io)?;
        match &mut prev {
            Some(p) => p.copy_from_slice(&idx),
            None => prev = Some(idx.clone()),
        }
        progress(i + 1, tl.frames);
    }
    let mut file = enc
        .into_inner()
        .with_context(|| format!("cannot write {}", path.display()))?;
    std::io::Write::flush(&mut file).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(flashed)
}

const PLATE: RGBColor = RGBColor(40, 70, 150);
const ARM: RGBColor = RGBColor(60, 60, 60);
const PIVOT: RGBColor = RGBColor(235, 130, 30);
const FLASHED: RGBColor = RGBColor(220, 30, 30);
const GROUND: RGBColor = RGBColor(200, 200, 195);
const REST: RGBColor = RGBColor(150, 150, 150);

/// Height of the text band at the top and of the timeline at the bottom (px).
const TOP: i32 = 64;
const BOTTOM: i32 = 34;

/// What every frame shares: the world-to-pixel map, the landings, the plant.
struct Scene<'a> {
    params: Params,
    trace: &'a Trace,
    /// Landing times (s) and the striking edge (world, m), in time order.
    landings: Vec<(f64, [f64; 2])>,
    /// Plant time window during which a landing is flashed (s).
    flash: f64,
    /// World point at the centre of the drawing (m) and its pixel position.
    centre: ([f64; 2], (f64, f64)),
    /// Pixels per metre.
    scale: f64,
    size: (u32, u32),
    tl: Timeline,
    speed: f64,
    /// The tilt's exaggeration.
    k: f64,
}

impl<'a> Scene<'a> {
    fn new(params: &Params, trace: &'a Trace, tl: &Timeline, opts: &Options) -> Self {
        let p = *params;
        // The bounding box of every pose in the window (with both edges and the arm upright
        // flat), so the camera stays still.
        let (mut lo, mut hi) = ([0.0f64, 0.0f64], [2.0 * p.f, 0.0f64]);
        let mut grow = |q: [f64; 2]| {
            lo = [lo[0].min(q[0]), lo[1].min(q[1])];
            hi = [hi[0].max(q[0]), hi[1].max(q[1])];
        };
        let flat = pose(&p, Mode::Flat, 0.0, std::f64::consts::FRAC_PI_2);
        grow(flat.tip);
        for s in trace
            .samples
            .iter()
            .filter(|s| s.t >= tl.t0 - tl.dt && s.t <= tl.t1 + tl.dt)
        {
            let q = pose(&p, s.mode, opts.tilt_exaggeration * s.x[0], s.x[1]);
            for v in [q.left, q.right, q.tip] {
                grow(v);
            }
        }
        let pad = 0.12 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(p.f);
        // Room below the ground for the pivot wedge.
        let (lo, hi) = (
            [lo[0] - pad, lo[1].min(0.0) - pad],
            [hi[0] + pad, hi[1] + pad],
        );
        let (w, h) = (opts.size.0 as f64, opts.size.1 as f64);
        let avail = (w, h - (TOP + BOTTOM) as f64);
        let scale = (avail.0 / (hi[0] - lo[0])).min(avail.1 / (hi[1] - lo[1]));
        let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let landings = trace
            .events
            .iter()
            .filter(|e| e.to == Mode::Flat && e.from.is_tilted())
            .map(|e| {
                // Tilted left, the plate falls back onto its right edge, and vice versa.
                let edge = match e.from {
                    Mode::Left => [2.0 * p.f, 0.0],
                    _ => [0.0, 0.0],
                };
                (e.t, edge)
            })
            .collect();
        Scene {
            params: p,
            trace,
            landings,
            flash: (FLASH * opts.speed).max(tl.dt),
            centre: (mid, (0.5 * w, TOP as f64 + 0.5 * avail.1)),
            scale,
            size: opts.size,
            tl: *tl,
            speed: opts.speed,
            k: opts.tilt_exaggeration,
        }
    }

    fn px(&self, q: [f64; 2]) -> (i32, i32) {
        let (c, (cx, cy)) = self.centre;
        (
            (cx + (q[0] - c[0]) * self.scale).round() as i32,
            (cy - (q[1] - c[1]) * self.scale).round() as i32,
        )
    }

    /// The landing flashed at plant time `t`: one within `(t - flash, t]`.
    fn flash_at(&self, t: f64) -> Option<(f64, [f64; 2])> {
        let i = self.landings.partition_point(|l| l.0 <= t);
        let l = *self.landings.get(i.checked_sub(1)?)?;
        (t - l.0 < self.flash).then_some(l)
    }

    /// Draws the frame at plant time `t`; `true` when a landing is flashed.
    fn draw(&self, root: &DrawingArea<BitMapBackend, Shift>, t: f64) -> Result<bool> {
        let (mode, alpha, beta) =
            state_at(&self.trace.samples, t).ok_or_else(|| anyhow!("no samples"))?;
        let p = &self.params;
        // The plate as drawn: its tilt times the exaggeration.
        let shown = self.k * alpha;
        let q = pose(p, mode, shown, beta);
        let flash = self.flash_at(t);
        let (w, h) = (self.size.0 as i32, self.size.1 as i32);
        root.fill(&WHITE)?;

        // Ground: a band below y = 0 across the frame.
        let g = self.px([0.0, 0.0]).1;
        let ground = if flash.is_some() {
            FLASHED.mix(0.25)
        } else {
            GROUND.mix(1.0)
        };
        root.draw(&Rectangle::new(
            [(0, g), (w, (h - BOTTOM).max(g))],
            ground.filled(),
        ))?;
        root.draw(&PathElement::new(
            vec![(0, g), (w, g)],
            BLACK.stroke_width(2),
        ))?;

        // Contact markers: a wedge under each resting edge; the active pivot larger, in orange.
        let wedge = |at: [f64; 2], r: i32, c: RGBColor| {
            let (x, y) = self.px(at);
            Polygon::new(
                vec![(x, y), (x - r, y + 2 * r), (x + r, y + 2 * r)],
                c.filled(),
            )
        };
        match q.pivot {
            Some(v) => root.draw(&wedge(v, 9, PIVOT))?,
            None => {
                root.draw(&wedge(q.left, 6, REST))?;
                root.draw(&wedge(q.right, 6, REST))?;
            }
        }

        // The plate: a slab of thickness 0.1 f above its contact line.
        let th = 0.1 * p.f;
        let n = [-shown.sin() * th, shown.cos() * th];
        let slab = vec![
            self.px(q.left),
            self.px(q.right),
            self.px([q.right[0] + n[0], q.right[1] + n[1]]),
            self.px([q.left[0] + n[0], q.left[1] + n[1]]),
        ];
        let plate = if flash.is_some() { FLASHED } else { PLATE };
        root.draw(&Polygon::new(slab, plate.filled()))?;

        // The arm and its masses.
        let r_tip = (0.07 * p.l * self.scale).clamp(4.0, 14.0) as i32;
        root.draw(&PathElement::new(
            vec![self.px(q.centre), self.px(q.tip)],
            ARM.stroke_width((0.02 * p.l * self.scale).clamp(2.0, 6.0) as u32),
        ))?;
        root.draw(&Circle::new(self.px(q.centre), r_tip / 2 + 2, ARM.filled()))?;
        root.draw(&Circle::new(self.px(q.tip), r_tip, ARM.filled()))?;

        // The flash: a ring around the edge that struck the ground.
        if let Some((_, edge)) = flash {
            let c = self.px(edge);
            root.draw(&Circle::new(c, 14, FLASHED.stroke_width(3)))?;
            root.draw(&Text::new(
                "impact",
                (c.0 - 24, c.1 + 20),
                ("sans-serif", 16).into_font().color(&FLASHED),
            ))?;
        }

        self.draw_readouts(root, t, mode, alpha, beta)?;
        self.draw_timeline(root, t)?;
        Ok(flash.is_some())
    }

    /// The frame's readouts at plant time `t`: the time, the mode, the angles `alpha` and
    /// `beta` (rad), an early stop, the tilt's exaggeration and the playback speed.
    fn draw_readouts(
        &self,
        root: &DrawingArea<BitMapBackend, Shift>,
        t: f64,
        mode: Mode,
        alpha: f64,
        beta: f64,
    ) -> Result<()> {
        let w = self.size.0 as i32;
        let font = ("sans-serif", 20).into_font();
        let small = ("sans-serif", 16).into_font();
        // Enough decimals to tell consecutive frames apart.
        let digits = (-self.tl.dt.log10()).ceil().clamp(2.0, 6.0) as usize;
        root.draw(&Text::new(
            format!("t = {t:.digits$} s"),
            (10, 8),
            font.clone(),
        ))?;
        let what = match mode {
            Mode::Flat => "flat",
            Mode::Left => "tilted left (pivot: left edge)",
            Mode::Right => "tilted right (pivot: right edge)",
        };
        let mode_style = font
            .clone()
            .color(&if mode.is_tilted() { PIVOT } else { BLACK });
        root.draw(&Text::new(what, (170, 8), mode_style))?;
        root.draw(&Text::new(
            format!("α = {alpha:+.4} rad   β = {beta:.4} rad"),
            (10, 36),
            small.clone(),
        ))?;
        if self.trace.stopped_early && t >= self.trace.end - 0.5 * self.tl.dt {
            root.draw(&Text::new(
                "the run stopped early here",
                (w / 2 - 90, TOP - 4),
                small.clone().color(&FLASHED),
            ))?;
        }
        if self.k != 1.0 {
            root.draw(&Text::new(
                format!("tilt drawn ×{}", self.k),
                (w - 240, 36),
                small.clone().color(&PIVOT),
            ))?;
        }
        if self.speed != 1.0 {
            root.draw(&Text::new(
                format!("speed ×{}", self.speed),
                (w - 110, 36),
                small.clone(),
            ))?;
        }

        Ok(())
    }

    /// The timeline under the frame: the window, the landings as ticks, plant time `t` (s) as
    /// a bar.
    fn draw_timeline(&self, root: &DrawingArea<BitMapBackend, Shift>, t: f64) -> Result<()> {
        let (w, h) = (self.size.0 as i32, self.size.1 as i32);
        let (x0, x1) = (10, w - 10);
        let y = h - BOTTOM / 2;
        let span = (self.tl.t1 - self.tl.t0).max(1e-9);
        let tx =
            |t: f64| x0 + (((t - self.tl.t0) / span).clamp(0.0, 1.0) * (x1 - x0) as f64) as i32;
        root.draw(&PathElement::new(
            vec![(x0, y), (x1, y)],
            REST.stroke_width(2),
        ))?;
        for l in self
            .landings
            .iter()
            .filter(|l| l.0 >= self.tl.t0 && l.0 <= self.tl.t1)
        {
            let x = tx(l.0);
            root.draw(&PathElement::new(
                vec![(x, y - 6), (x, y + 6)],
                FLASHED.mix(0.6).stroke_width(1),
            ))?;
        }
        root.draw(&Rectangle::new(
            [(tx(t) - 2, y - 9), (tx(t) + 2, y + 9)],
            BLACK.filled(),
        ))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};
    use tilting_sim::closed_loop::EventRecord;

    /// Each option out of range is refused naming its flag; the edges of the ranges pass.
    #[test]
    fn options_out_of_range_name_their_flag() {
        let ok = Options::default();
        ok.validate().unwrap();
        let edges = Options {
            fps: MAX_FPS,
            size: (160, 120),
            tilt_exaggeration: 100.0,
            start: Some(1.0),
            end: Some(1.5),
            ..ok.clone()
        };
        edges.validate().unwrap();
        for (bad, flag) in [
            (
                Options {
                    fps: 0.0,
                    ..ok.clone()
                },
                "`--fps` = 0",
            ),
            (
                Options {
                    fps: MAX_FPS + 1.0,
                    ..ok.clone()
                },
                "`--fps` = 51",
            ),
            (
                Options {
                    speed: f64::NAN,
                    ..ok.clone()
                },
                "`--speed` = NaN",
            ),
            (
                Options {
                    start: Some(f64::INFINITY),
                    ..ok.clone()
                },
                "`--start` = inf",
            ),
            (
                Options {
                    size: (159, 480),
                    ..ok.clone()
                },
                "`--size` = 159x480",
            ),
            (
                Options {
                    size: (640, 4097),
                    ..ok.clone()
                },
                "`--size` = 640x4097",
            ),
            (
                Options {
                    start: Some(2.0),
                    end: Some(2.0),
                    ..ok.clone()
                },
                "`--end` = 2",
            ),
            (
                Options {
                    tilt_exaggeration: 0.5,
                    ..ok.clone()
                },
                "`--tilt-exaggeration` = 0.5",
            ),
        ] {
            let e = bad.validate().expect_err(flag).to_string();
            assert!(e.contains(flag), "{flag}: {e}");
        }
    }

    fn close(a: [f64; 2], b: [f64; 2]) -> bool {
        (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12
    }

    #[test]
    fn pose_matches_closed_forms() {
        let p = Params::default();
        let (f, l) = (p.f, p.l);
        // Flat, arm upright: the plate on [0, 2f], the tip straight above the centre.
        let q = pose(&p, Mode::Flat, 0.0, FRAC_PI_2);
        assert!(close(q.left, [0.0, 0.0]) && close(q.right, [2.0 * f, 0.0]));
        assert!(close(q.centre, [f, 0.0]) && close(q.tip, [f, l]));
        assert_eq!(q.pivot, None);
        // Tilted left by a: the left edge stays put, the right edge rises on the circle.
        let (a, b) = (0.3, 1.2);
        let q = pose(&p, Mode::Left, a, b);
        assert_eq!(q.pivot, Some([0.0, 0.0]));
        assert!(close(q.left, [0.0, 0.0]));
        assert!(close(q.right, [2.0 * f * a.cos(), 2.0 * f * a.sin()]));
        assert!(close(q.centre, [f * a.cos(), f * a.sin()]));
        let tip = [
            f * a.cos() + l * (a + b).cos(),
            f * a.sin() + l * (a + b).sin(),
        ];
        assert!(close(q.tip, tip));
        // Tilted right by -a: the right edge stays put, the left edge rises.
        let q = pose(&p, Mode::Right, -a, b);
        assert_eq!(q.pivot, Some([2.0 * f, 0.0]));
        assert!(close(q.right, [2.0 * f, 0.0]));
        assert!(close(
            q.left,
            [2.0 * f - 2.0 * f * a.cos(), 2.0 * f * a.sin()]
        ));
        assert!(q.left[1] > 0.0);
        // The plate keeps its length and the arm its length.
        let d = |u: [f64; 2], v: [f64; 2]| (u[0] - v[0]).hypot(u[1] - v[1]);
        assert!((d(q.left, q.right) - 2.0 * f).abs() < 1e-12);
        assert!((d(q.centre, q.tip) - l).abs() < 1e-12);
    }

    #[test]
    fn pose_is_mirror_symmetric() {
        // (alpha, beta) -> (-alpha, pi - beta) with left and right swapped mirrors the picture
        // about the vertical line x = f.
        let p = Params::default();
        let m = |v: [f64; 2]| [2.0 * p.f - v[0], v[1]];
        for (mode, a, b) in [
            (Mode::Left, 0.2, 1.1),
            (Mode::Flat, 0.0, 2.0),
            (Mode::Left, 1.0, 0.1),
        ] {
            let q = pose(&p, mode, a, b);
            let r = pose(&p, mode.mirrored(), -a, PI - b);
            assert!(close(m(q.left), r.right) && close(m(q.right), r.left));
            assert!(close(m(q.centre), r.centre) && close(m(q.tip), r.tip));
            assert_eq!(q.pivot.map(m), r.pivot);
        }
    }

    fn sample(t: f64, mode: Mode, a: f64, b: f64) -> Sample {
        Sample {
            t,
            mode,
            x: [a, b, 0.0, 0.0],
        }
    }

    #[test]
    fn state_interpolates_within_a_mode_and_holds_across_events() {
        let s = [
            sample(0.0, Mode::Left, 0.0, 1.0),
            sample(1.0, Mode::Left, 0.2, 2.0),
            sample(2.0, Mode::Left, 0.0, 1.5),
            sample(2.0, Mode::Right, 0.0, 1.5),
            sample(3.0, Mode::Right, -0.3, 1.0),
        ];
        assert_eq!(state_at(&s, -1.0), Some((Mode::Left, 0.0, 1.0)));
        let (m, a, b) = state_at(&s, 0.5).unwrap();
        assert_eq!(m, Mode::Left);
        assert!((a - 0.1).abs() < 1e-15 && (b - 1.5).abs() < 1e-15);
        assert_eq!(state_at(&s, 2.0).unwrap().0, Mode::Right);
        let (m, a, _) = state_at(&s, 2.5).unwrap();
        assert!(m == Mode::Right && (a + 0.15).abs() < 1e-15);
        assert_eq!(state_at(&s, 9.0), Some((Mode::Right, -0.3, 1.0)));
        assert_eq!(state_at(&[], 0.0), None);
    }

    #[test]
    fn timeline_counts_frames_and_rejects_bad_options() {
        let s = [
            sample(0.0, Mode::Flat, 0.0, 1.0),
            sample(4.0, Mode::Flat, 0.0, 1.0),
        ];
        let tr = Trace {
            samples: s.to_vec(),
            events: Vec::new(),
            end: 4.0,
            stopped_early: false,
        };
        let tl = timeline(&tr, &Options::default()).unwrap();
        assert_eq!((tl.frames, tl.delay_cs), (101, 4));
        let o = Options {
            speed: 0.5,
            start: Some(1.0),
            end: Some(2.0),
            ..Options::default()
        };
        assert_eq!(timeline(&tr, &o).unwrap().frames, 51);
        for bad in [
            Options {
                fps: 0.0,
                ..Options::default()
            },
            Options {
                fps: 60.0,
                ..Options::default()
            },
            Options {
                speed: -1.0,
                ..Options::default()
            },
            Options {
                tilt_exaggeration: 0.5,
                ..Options::default()
            },
            Options {
                start: Some(3.0),
                end: Some(2.0),
                ..Options::default()
            },
        ] {
            assert!(timeline(&tr, &bad).is_err(), "{bad:?}");
        }
        let none = Trace {
            samples: Vec::new(),
            ..tr
        };
        assert!(timeline(&none, &Options::default()).is_err());
    }

    #[test]
    fn gif_decodes_with_the_expected_frames_and_flashes() {
        // Half a second: a left tilt that lands at 0.2 s and a right tilt after it.
        let mut s = Vec::new();
        for k in 0..=20 {
            let t = k as f64 * 0.01;
            s.push(sample(t, Mode::Left, 0.1 * (PI * t / 0.2).sin(), FRAC_PI_2));
        }
        for k in 20..=50 {
            let t = k as f64 * 0.01;
            s.push(sample(
                t,
                Mode::Right,
                -0.1 * (PI * (t - 0.2) / 0.3).sin(),
                FRAC_PI_2,
            ));
        }
        let ev = |from, to| EventRecord {
            t: 0.19,
            from,
            to,
            x_before: [0.0; 4],
            x_after: [0.0; 4],
        };
        let events = [ev(Mode::Left, Mode::Flat), ev(Mode::Flat, Mode::Right)];
        let tr = Trace {
            samples: s,
            events: events.to_vec(),
            end: 0.5,
            stopped_early: false,
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.gif");
        let opts = Options {
            size: (320, 240),
            ..Options::default()
        };
        let calls = std::cell::Cell::new(0);
        let progress = |done, all| {
            calls.set(calls.get() + 1);
            assert_eq!((done, all), (calls.get(), 13));
        };
        let r = animate(
            Output::Gif(&path),
            &Params::default(),
            &tr,
            &opts,
            &progress,
        )
        .unwrap();
        assert_eq!(calls.get(), 13, "one call per frame");
        // 0.5 s at 25 fps: frames at 0, 0.04, ..., 0.48; the landing (at 0.19 s, off the frame
        // times) flashes for 0.12 s: the frames at 0.20, 0.24 and 0.28.
        assert_eq!(r.timeline.frames, 13);
        assert_eq!(r.flashed, 3);
        let mut d = gif::DecodeOptions::new();
        d.set_color_output(gif::ColorOutput::RGBA);
        let mut d = d.read_info(std::fs::File::open(&path).unwrap()).unwrap();
        assert_eq!((d.width(), d.height()), (320, 240));
        let mut n = 0;
        let mut red = Vec::new();
        // Frames after the first are rectangles over the previous one: compose them.
        let mut canvas = vec![0u8; 320 * 240 * 4];
        while let Some(f) = d.read_next_frame().unwrap() {
            assert_eq!(f.delay, 4);
            let (l, t, fw) = (f.left as usize, f.top as usize, f.width as usize);
            for (y, row) in f.buffer.chunks(fw * 4).enumerate() {
                let at = ((t + y) * 320 + l) * 4;
                canvas[at..at + fw * 4].copy_from_slice(row);
            }
            // Count strongly red pixels: the flashed plate and ring.
            let reds = canvas
                .chunks(4)
                .filter(|p| p[0] > 180 && p[1] < 90 && p[2] < 90)
                .count();
            red.push(reds);
            n += 1;
        }
        assert_eq!(n, 13);
        // The composed last frame is the frame drawn directly, in the palette's colours.
        let tl = timeline(&tr, &opts).unwrap();
        let scene = Scene::new(&Params::default(), &tr, &tl, &opts);
        let mut rgb = vec![0u8; 320 * 240 * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (320, 240)).into_drawing_area();
            scene.draw(&root, tl.time(12)).unwrap();
        }
        let mut idx = vec![0u8; 320 * 240];
        quantise(&rgb, &mut idx);
        let pal = cube_palette();
        let differ = idx
            .iter()
            .zip(canvas.chunks(4))
            .filter(|(&k, c)| pal[3 * k as usize..3 * k as usize + 3] != c[..3])
            .count();
        assert_eq!(differ, 0);
        let flashed: Vec<bool> = red.iter().map(|&r| r > 50).collect();
        let expect: Vec<bool> = (0..13).map(|i| (5..8).contains(&i)).collect();
        assert_eq!(flashed, expect, "red pixels per frame: {red:?}");
    }
}
