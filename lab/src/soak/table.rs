//! The soak's report as a Markdown table, and the command line that made it.

use std::fmt::Write as _;
use std::path::Path;

use super::{SoakOptions, SoakReport, IDLE_AFTER, WARM_UP};
use crate::table::Table;

impl SoakReport {
    /// The report as a Markdown table.
    pub fn to_markdown(&self, opts: &SoakOptions) -> String {
        let h = &self.health;
        let rows: Vec<(&str, String)> = vec![
            (
                "run",
                format!(
                    "{:.1} s, scene `{}`, {} clients",
                    self.seconds,
                    opts.scene.display(),
                    opts.clients
                ),
            ),
            (
                "frames stepped",
                format!(
                    "{} in {:.1} s; {:.2} s from the kill until the resumed server answered",
                    self.frames, self.seconds, self.downtime
                ),
            ),
            (
                "step rate while up",
                self.rates
                    .iter()
                    .map(|r| format!("{:.1}% of real time", r * self.dt * 100.0))
                    .collect::<Vec<_>>()
                    .join(" before the kill, ")
                    + if self.rates.len() > 1 {
                        " after the resume"
                    } else {
                        ""
                    },
            ),
            ("overruns (steps started late)", self.overruns.to_string()),
            (
                "step time p50 / p99 / max",
                format!(
                    "{:.3} / {:.3} / {:.3} ms",
                    self.step_ms_p50, self.step_ms_p99, self.step_ms_max
                ),
            ),
            (
                "commands sent",
                format!(
                    "{} ({} invalid, {} oversized)",
                    self.commands_sent, self.invalid_sent, self.oversized_sent
                ),
            ),
            (
                "applied / refused / rate-limited / queue full",
                format!(
                    "{} / {} / {} / {}",
                    h.applied, h.refused, h.rate_limited, h.queue_full
                ),
            ),
            (
                "requests sent / answered / missed",
                format!(
                    "{} / {} / {}",
                    self.requests_sent, self.requests_answered, self.requests_missed
                ),
            ),
            (
                "retries answered from the first answer",
                h.retries.to_string(),
            ),
            (
                "accepted requests not in the journal",
                self.accepted_not_journaled.to_string(),
            ),
            ("journal at the end", format!("{:.1} MiB", self.journal_mib)),
            (
                "replies and events unsent (slow peers)",
                h.unsent.to_string(),
            ),
        ];
        let mut t = Table::new(["figure", "value"]);
        for (k, v) in rows {
            t.row([k.to_string(), v]);
        }
        // The goal's figure: the world's memory with its clients connected and quiet, before
        // any load (the first server's start), against the server that ran to the end, idle
        // after the load.
        if let (Some(first), Some(idle)) = (self.rss.first(), self.rss.last().and_then(|m| m.idle))
        {
            t.row([
                "allocated memory back after the load".to_string(),
                format!(
                    "{:.2} MiB before the load, {idle:.2} MiB {} s after it ended ({:+.1}%)",
                    first.start,
                    IDLE_AFTER.as_secs(),
                    (idle / first.start - 1.0) * 100.0
                ),
            ]);
        }
        for (i, m) in self.rss.iter().enumerate() {
            let which = if i == 0 && self.rss.len() > 1 {
                "killed server"
            } else if i > 0 {
                "resumed server"
            } else {
                "server"
            };
            let warm = m
                .warm
                .map(|w| {
                    format!(
                        ", {w:.2} after {} s ({:+.1}% from then to the end)",
                        WARM_UP.as_secs(),
                        (m.end / w - 1.0) * 100.0
                    )
                })
                .unwrap_or_default();
            t.row([format!("allocated memory (resident, anonymous), {which}"), format!("{:.2} MiB at start{warm}, {:.2} peak, {:.2} at end ({:+.1}% against the start)", m.start, m.peak, m.end, (m.end / m.start - 1.0) * 100.0)]);
            if let Some(idle) = m.idle {
                t.row([
                    format!(
                        "allocated memory {} s after the load ended, {which}",
                        IDLE_AFTER.as_secs()
                    ),
                    format!(
                        "{idle:.2} MiB ({:+.1}% against the start)",
                        (idle / m.start - 1.0) * 100.0
                    ),
                ]);
            }
            t.row([
                format!("whole resident set (code pages included), {which}"),
                format!(
                    "{:.1} MiB at start, {:.1} at end ({:+.1}%)",
                    m.total_start,
                    m.total_end,
                    (m.total_end / m.total_start - 1.0) * 100.0
                ),
            ]);
            t.row([
                format!("threads, {which}"),
                format!("{} at start, {} at the end", m.threads_start, m.threads_end),
            ]);
        }
        t.to_string()
    }
}

impl SoakReport {
    /// Writes the table between the `soak` markers of `out`, saying the command and
    /// machine that measured it.
    pub fn write(&self, opts: &SoakOptions, out: &Path) -> anyhow::Result<()> {
        crate::splice(
            out,
            "soak",
            &format!(
                "Measured by `{}` on {}.\n\n{}",
                command_line(opts, Some(out)),
                crate::machine(),
                self.to_markdown(opts)
            ),
        )
    }
}

/// The options of the soak as run for docs/reliability.md, as a command line.
pub fn command_line(opts: &SoakOptions, out: Option<&Path>) -> String {
    let mut s = format!(
        "ricochet-lab soak --scene {} --seconds {} --clients {} --rate {} --requests {} --stall-at {} --stall-for {}",
        opts.scene.display(), opts.seconds, opts.clients, opts.rate, opts.requests, opts.stall_at, opts.stall_for
    );
    if let Some(k) = opts.kill_at {
        let _ = write!(s, " --kill-at {k}");
    }
    if let Some(out) = out {
        let _ = write!(s, " --out {}", out.display());
    }
    s
}
