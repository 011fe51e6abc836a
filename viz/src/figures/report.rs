//! Drawing several figures in one go ([`Figures::draw_all`]) and what it reports.

use super::{Figures, Summary};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Instant;

/// What `tilting figures --json` prints (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FiguresReport {
    /// The figures that failed: `figN: why`.
    pub failed: Vec<String>,
    /// The figures drawn, in the order of [`super::ALL`].
    pub figures: Vec<FigureReport>,
    /// The landing impact law.
    pub impact: String,
    /// The output directory.
    pub out: PathBuf,
    /// Coarse grids and short runs (`--quick`).
    pub quick: bool,
    /// Wall-clock time of all the figures (s).
    pub seconds: f64,
}

/// One figure drawn.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FigureReport {
    /// Its id: "4" to "8", "8b", "8c".
    pub figure: String,
    /// The PNG file.
    pub path: PathBuf,
    /// Wall-clock time of this figure (s).
    pub seconds: f64,
    /// What it shows.
    pub summary: Summary,
}

/// How [`Figures::draw_all`] reports its progress, in the units of [`Figures::units`].
pub trait FiguresProgress: Sync {
    /// Figure `id` begins.
    fn figure(&self, id: &str);
    /// One more unit done (from several threads).
    fn tick(&self);
    /// `units` done in all: each figure ends at its share, whatever its ticks were.
    fn reached(&self, units: u64);
}

impl Figures {
    /// Draws the figures `which` (ids of [`super::ALL`], in the order given), each into
    /// [`Figures::path`]; one that fails is listed with why in [`FiguresReport::failed`] and the
    /// others are still drawn. `quick` is recorded in the report (the grids are
    /// [`Figures::set`]'s).
    pub fn draw_all(
        &self,
        which: &[&str],
        quick: bool,
        progress: &dyn FiguresProgress,
    ) -> FiguresReport {
        let start = Instant::now();
        let (mut done, mut failed, mut reached) = (Vec::new(), Vec::new(), 0);
        for &n in which {
            progress.figure(n);
            let t0 = Instant::now();
            let r = self.draw(n, &|| progress.tick());
            // 8b and 8c give an upper bound of their ticks: each figure ends at its share.
            reached += self.units(n);
            progress.reached(reached);
            match r {
                Ok(summary) => done.push(FigureReport {
                    figure: n.to_owned(),
                    path: self.path(n),
                    seconds: t0.elapsed().as_secs_f64(),
                    summary,
                }),
                Err(e) => failed.push(format!("fig{n}: {e:#}")),
            }
        }
        FiguresReport {
            out: self.out.clone(),
            quick,
            impact: self.impact.as_str().to_owned(),
            seconds: start.elapsed().as_secs_f64(),
            figures: done,
            failed,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::figures::Settings;
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Mutex;

    #[derive(Default)]
    struct Seen {
        figures: Mutex<Vec<String>>,
        ticks: AtomicU64,
        reached: AtomicU64,
    }

    impl FiguresProgress for Seen {
        fn figure(&self, id: &str) {
            self.figures.lock().unwrap().push(id.to_owned());
        }
        fn tick(&self) {
            self.ticks.fetch_add(1, Ordering::Relaxed);
        }
        fn reached(&self, units: u64) {
            self.reached.store(units, Ordering::Relaxed);
        }
    }

    /// A figure that cannot be drawn is listed with why and the next is still drawn; the
    /// progress names each figure, ends at the sum of their units, and ticks no more than that.
    #[test]
    fn a_failed_figure_is_listed_and_the_rest_drawn() {
        let dir = tempfile::tempdir().unwrap();
        let params = tilting_plant::Params::default();
        let figs = Figures {
            params,
            impact: params.impact,
            set: Settings::quick(),
            out: dir.path().to_path_buf(),
        };
        let seen = Seen::default();
        let r = figs.draw_all(&["9", "7"], true, &seen);
        assert_eq!(r.failed.len(), 1, "{:?}", r.failed);
        assert!(
            r.failed[0].starts_with("fig9: no figure `9`"),
            "{:?}",
            r.failed
        );
        assert_eq!(r.figures.len(), 1);
        assert_eq!(r.figures[0].figure, "7");
        assert!(r.figures[0].path.is_file());
        assert_eq!(r.figures[0].path, dir.path().join("fig7.png"));
        assert!(r.quick && r.out == dir.path());
        assert_eq!(*seen.figures.lock().unwrap(), ["9", "7"]);
        assert_eq!(seen.reached.load(Ordering::Relaxed), figs.units("7"));
        assert!(seen.ticks.load(Ordering::Relaxed) <= figs.units("7"));
    }
}
