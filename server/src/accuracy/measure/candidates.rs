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
    // The default's family first, cheapest to finest: the impulse solver with split
    // impulses and the resting load, at more sub-steps (mass ratios, fast bodies) and more
    // passes (tall piles). Every field that makes it the default is named, so a scene that
    // names the chapter's relaxation gets the same setting.
    for (substeps, passes) in [(1, 2), (2, 2), (2, 4), (4, 4), (8, 4), (8, 8)] {
        out.push(impulse_ladder(substeps, passes));
    }
    out.push(c(
        "soft 1 pass + 1 relax, 4 sub-steps",
        &[
            "solver=impulses",
            "broad_phase=grid",
            "impulse_iterations=1",
            "relax_iterations=1",
            "substeps=4",
            "contact_hertz=30",
            "split_impulses=false",
        ],
    ));
    let relaxation = |n: u32| format!("relaxation_iterations={n}");
    for n in [15, 50] {
        out.push(Candidate {
            name: format!("relaxation {n}"),
            overrides: vec![
                "solver=relaxation".into(),
                "broad_phase=sweep".into(),
                relaxation(n),
                "substeps=1".into(),
            ],
        });
    }
    out.push(c(
        "relaxation 15, 4 sub-steps",
        &[
            "solver=relaxation",
            "broad_phase=sweep",
            "relaxation_iterations=15",
            "substeps=4",
        ],
    ));
    out.push(c(
        "impulses 8 passes, cold, 1 sub-step",
        &[
            "solver=impulses",
            "broad_phase=grid",
            "impulse_iterations=8",
            "substeps=1",
            "split_impulses=false",
            "rest_load=false",
            "shock_propagation=false",
        ],
    ));
    let with = |extra: &[&str]| -> Vec<String> {
        impulse_ladder(2, 2)
            .overrides
            .into_iter()
            .chain(extra.iter().map(|s| s.to_string()))
            .collect()
    };
    out.push(Candidate {
        name: "impulses 2 x 2, exact flight".into(),
        overrides: with(&["integrator=exact"]),
    });
    if f.fast {
        out.push(Candidate {
            name: "impulses 2 x 2, continuous collision".into(),
            overrides: with(&["ccd=true"]),
        });
    }
    // Sleeping is the default's: where islands could sleep, the same setting awake (what a
    // pile that has come to rest costs if it is stepped on).
    if f.dynamic >= 64 {
        out.push(Candidate {
            name: "impulses 2 x 2, awake".into(),
            overrides: with(&["sleeping=false"]),
        });
    }
    out
}

/// The default's solver at `substeps` sub-steps of `passes` passes (the default is 2 x 2).
pub fn impulse_ladder(substeps: u32, passes: u32) -> Candidate {
    Candidate {
        name: format!(
            "impulses {substeps} sub-step{} x {passes} passes{}",
            if substeps == 1 { "" } else { "s" },
            if (substeps, passes) == (2, 2) {
                " (the default)"
            } else {
                ""
            }
        ),
        overrides: vec![
            "solver=impulses".into(),
            "broad_phase=grid".into(),
            format!("substeps={substeps}"),
            format!("impulse_iterations={passes}"),
            "split_impulses=true".into(),
            "rest_load=true".into(),
            "shock_propagation=true".into(),
            "warm_starting=true".into(),
            "relax_iterations=0".into(),
            "contact_hertz=0".into(),
        ],
    }
}
