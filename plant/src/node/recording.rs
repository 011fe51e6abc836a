//! The plant's `--record FILE`: an MCAP recording of what the plant publishes and applies
//! (`tilting_record`), or, for a file named `*.csv`, one CSV row per period for spreadsheets.
//!
//! MCAP channels: every state once (re-publications of a state while the plant waits are not
//! repeated), every event, every status, and every torque command the plant *applied* (its
//! bytes as received; a safe-mode period applies no command). So the counts equal the
//! summary's `steps + 1`, `transitions` and `torques_applied`.

use super::csv::RowWriter;
use super::STATE_COLUMNS;
use anyhow::Context as _;
use std::path::Path;
use tilting_proto::{encode, Keys, ModeEvent, PlantState, Status, Topic, TorqueCommand};
use tilting_record::McapWriter;

/// An open `--record` file.
pub(super) enum Recording {
    /// `*.csv`: `seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau` rows.
    Csv(RowWriter),
    /// Anything else: MCAP.
    Mcap {
        rec: Box<McapWriter>,
        last_state: Option<u64>,
    },
}

impl Recording {
    /// Creates `path`: CSV if its extension is `csv`, MCAP otherwise.
    pub(super) fn create(path: &Path, keys: &Keys) -> anyhow::Result<Self> {
        let csv = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        Ok(if csv {
            Recording::Csv(
                RowWriter::create(path, &format!("{STATE_COLUMNS},tau"), RowWriter::INTERVAL)
                    .with_context(|| format!("--record {}", path.display()))?,
            )
        } else {
            Recording::Mcap {
                rec: Box::new(McapWriter::create(path, keys).context("--record")?),
                last_state: None,
            }
        })
    }

    /// A published state (MCAP; once per `seq`).
    pub(super) fn state(&mut self, s: &PlantState) -> anyhow::Result<()> {
        if let Recording::Mcap { rec, last_state } = self {
            if last_state.is_none_or(|l| s.seq > l) {
                *last_state = Some(s.seq);
                rec.record(Topic::State, &encode(s))?;
            }
        }
        Ok(())
    }

    /// A published event (MCAP).
    pub(super) fn event(&mut self, e: &ModeEvent) -> anyhow::Result<()> {
        if let Recording::Mcap { rec, .. } = self {
            rec.record(Topic::Event, &encode(e))?;
        }
        Ok(())
    }

    /// A published status (MCAP).
    pub(super) fn status(&mut self, s: &Status) -> anyhow::Result<()> {
        if let Recording::Mcap { rec, .. } = self {
            rec.record(Topic::Status, &encode(s))?;
        }
        Ok(())
    }

    /// A torque command taken into force (MCAP).
    pub(super) fn torque(&mut self, c: &TorqueCommand) -> anyhow::Result<()> {
        if let Recording::Mcap { rec, .. } = self {
            rec.record(Topic::Torque, &encode(c))?;
        }
        Ok(())
    }

    /// One CSV row: the state at the start of a period and the torque integrated over it
    /// (`None` for the last row).
    pub(super) fn row(
        &mut self,
        seq: u64,
        t: f64,
        mode: u8,
        x: [f64; 4],
        tau: Option<f64>,
    ) -> anyhow::Result<()> {
        if let Recording::Csv(w) = self {
            let tau = tau.map(|t| t.to_string()).unwrap_or_default();
            w.row(format_args!(
                "{seq},{t},{mode},{},{},{},{},{tau}",
                x[0], x[1], x[2], x[3]
            ))?;
        }
        Ok(())
    }

    /// Writes what is pending if the flush interval has passed.
    pub(super) fn flush_if_due(&mut self) -> anyhow::Result<()> {
        match self {
            Recording::Csv(w) => w.flush_if_due()?,
            Recording::Mcap { rec, .. } => rec.flush_if_due()?,
        }
        Ok(())
    }

    /// Writes everything and closes the file (MCAP: with its summary section).
    pub(super) fn finish(self) -> anyhow::Result<()> {
        match self {
            Recording::Csv(mut w) => w.flush()?,
            Recording::Mcap { mut rec, .. } => rec.finish()?,
        }
        Ok(())
    }
}
