//! Figures of the tilting system, drawn with `plotters` into PNG files with an embedded font
//! (no system fonts needed):
//!
//! - [`plot`]: the small plotting toolkit (font registration, padded ranges) and the plot of an
//!   offline run (`simulate --plot`) and of a live recording (`run.png`);
//! - [`animate`]: the plate and the arm of a run, moving, as an animated GIF or PNG frames;
//! - [`continuation`]: Fig. 8b (the continued orbits over the sweep, the Lyapunov exponent)
//!   and Fig. 8c (the stability region in two parameters);
//! - [`reach`]: which gains reach a wanted tilt peak (`plan reach`);
//! - [`figures`]: the paper's Figs. 4 to 8, computed with `tilting-planner` and `tilting-sim`.
//!
//! This crate computes nothing of its own beyond what a figure needs to lay itself out: the
//! numerics live in the planner and the closed loop in `tilting-sim`.

#![warn(missing_docs)]

pub mod animate;
pub mod continuation;
pub mod figures;
pub mod margins;
pub mod plot;
pub mod reach;
