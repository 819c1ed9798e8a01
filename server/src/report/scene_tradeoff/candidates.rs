//! The candidate settings: `[world]` overrides, and the default matrix of the knobs that
//! act on a scene.

use anyhow::{bail, Result};

/// A setting measured: a name and the overrides of the scene's `[world]` it makes.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    pub name: String,
    pub overrides: Vec<String>,
}

impl Candidate {
    pub fn new(name: &str, overrides: &[&str]) -> Candidate {
        Candidate {
            name: name.to_string(),
            overrides: overrides.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// A candidate given on the command line: overrides separated by `;`
    /// (`solver=impulses;impulse_iterations=8`), named by themselves.
    pub fn parse(text: &str) -> Result<Candidate> {
        let overrides: Vec<String> = text
            .split(';')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(str::to_string)
            .collect();
        if overrides.is_empty() {
            bail!("candidate `{text}`: no NAME=VALUE overrides");
        }
        if let Some(bad) = overrides.iter().find(|o| !o.contains('=')) {
            bail!("candidate `{text}`: `{bad}` is not NAME=VALUE");
        }
        Ok(Candidate {
            name: overrides.join(", "),
            overrides,
        })
    }
}

/// What a scene holds and does, found by running it once under its own settings: what
/// the candidate matrix and the report need.
#[derive(Clone, Copy, Debug, Default)]
pub struct Features {
    pub dynamic: usize,
    pub statics: usize,
    /// Rigid contacts were resolved in some step.
    pub contacts: bool,
    /// Particles lived in some step.
    pub particles: bool,
    /// Some body moved more than a hundredth of the scene's size in a step: what
    /// continuous collision is for.
    pub fast: bool,
}

/// The default candidates for a scene with these features: only the knobs that act on it.
pub fn default_candidates(f: &Features) -> Vec<Candidate> {
    let c = Candidate::new;
    let mut out = vec![c("as the scene sets it", &[])];
    if !f.contacts {
        // Nothing touches: only the flight's integration and its step matter.
        for integrator in ["symplectic", "explicit", "exact"] {
            for substeps in [1, 2, 4] {
                out.push(Candidate {
                    name: format!(
                        "{integrator}, {substeps} sub-step{}",
                        if substeps > 1 { "s" } else { "" }
                    ),
                    overrides: vec![
                        format!("integrator={integrator}"),
                        format!("substeps={substeps}"),
                    ],
                });
            }
        }
        return out;
    }
    let relaxation = |n: u32| format!("relaxation_iterations={n}");
    for n in [5, 15, 50] {
        out.push(Candidate {
            name: format!("relaxation {n}"),
            overrides: vec![
                "solver=relaxation".into(),
                relaxation(n),
                "substeps=1".into(),
            ],
        });
    }
    out.push(c(
        "relaxation 15, 4 sub-steps",
        &[
            "solver=relaxation",
            "relaxation_iterations=15",
            "substeps=4",
        ],
    ));
    out.push(c(
        "relaxation 15, exact flight",
        &[
            "solver=relaxation",
            "relaxation_iterations=15",
            "substeps=1",
            "integrator=exact",
        ],
    ));
    for n in [4, 8, 16] {
        out.push(Candidate {
            name: format!("impulses {n} it"),
            overrides: vec![
                "solver=impulses".into(),
                format!("impulse_iterations={n}"),
                "substeps=1".into(),
            ],
        });
    }
    let impulses8 = ["solver=impulses", "impulse_iterations=8"];
    let with = |extra: &[&str]| -> Vec<String> {
        impulses8
            .iter()
            .chain(extra)
            .map(|s| s.to_string())
            .collect()
    };
    for (name, extra) in [
        ("impulses 8 it, 2 sub-steps", &["substeps=2"][..]),
        ("impulses 8 it, 4 sub-steps", &["substeps=4"]),
        (
            "impulses 8 it, split",
            &["substeps=1", "split_impulses=true"],
        ),
        (
            "impulses 8 it, exact flight",
            &["substeps=1", "integrator=exact"],
        ),
        (
            "impulses 8 it, no warm start",
            &["substeps=1", "warm_starting=false"],
        ),
        (
            "soft 1 it + 1 relax, 4 sub-steps",
            &[
                "impulse_iterations=1",
                "relax_iterations=1",
                "substeps=4",
                "contact_hertz=30",
            ],
        ),
    ] {
        out.push(Candidate {
            name: name.into(),
            overrides: with(extra),
        });
    }
    if f.fast {
        out.push(Candidate {
            name: "impulses 8 it, continuous collision".into(),
            overrides: with(&["substeps=1", "ccd=true"]),
        });
    }
    if f.dynamic >= 64 {
        out.push(Candidate {
            name: "impulses 8 it, grid".into(),
            overrides: with(&["substeps=1", "broad_phase=grid"]),
        });
        out.push(Candidate {
            name: "impulses 8 it, sleeping".into(),
            overrides: with(&["substeps=1", "sleeping=true"]),
        });
    }
    out
}
