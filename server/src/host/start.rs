//! The world a server starts with: resumed from its journal, or loaded from its scene
//! (under the setting its accuracy target picks) with a new journal if asked.

use anyhow::{anyhow, Context, Result};

use super::answered::Answered;
use super::hosted::Hosted;
use super::journal::{self, Journal};
use super::HostOptions;

/// A world ready to serve, with what it remembers and where it journals.
pub(super) struct Started {
    pub host: Hosted,
    pub answered: Answered,
    pub journal: Option<Journal>,
    /// The options as the world runs under them: a journal's when resumed, with the
    /// accuracy target's pick among the overrides otherwise.
    pub opts: HostOptions,
}

/// Resumes the journal `opts.resume` names, or the journal `opts.journal` names when that
/// file exists (a service restarted with the same command line goes on where it stopped),
/// or loads `opts.scene`.
pub(super) fn start(opts: &HostOptions) -> Result<Started> {
    let existing = opts
        .journal
        .as_ref()
        .filter(|path| std::fs::metadata(path).is_ok_and(|m| m.len() > 0));
    match opts.resume.as_ref().or(existing) {
        Some(path) => {
            if opts.resume.is_none() {
                tracing::info!(
                    journal = %path.display(),
                    "the journal exists: resuming it (its header gives the scene, world, overrides and limits)"
                );
            }
            let resumed = journal::resume(path, opts)?;
            let named = opts
                .scene
                .as_ref()
                .and_then(|s| std::fs::read_to_string(s).ok());
            if named.is_some_and(|text| text != resumed.host.source.text) {
                tracing::warn!(
                    scene = %opts.scene.as_ref().expect("named").display(),
                    "the scene file differs from the one the journal holds: the journal's runs (delete the journal to start the new scene)"
                );
            }
            tracing::info!(
                journal = %path.display(),
                world = %resumed.world,
                frame = resumed.host.world.frame(),
                remembered_ids = resumed.answered.len(),
                "resumed the world from its journal"
            );
            Ok(Started {
                host: resumed.host,
                answered: resumed.answered,
                journal: Some(resumed.journal),
                opts: resumed.opts,
            })
        }
        None => {
            let scene = opts
                .scene
                .as_ref()
                .ok_or_else(|| anyhow!("a scene, or a journal to resume, is needed"))?;
            let text = std::fs::read_to_string(scene)
                .with_context(|| format!("cannot read scene {}", scene.display()))?;
            let mut opts = opts.clone();
            // The pick's overrides are journaled with the rest: a resume needs no measure.
            let picked = crate::accuracy::apply_to(
                scene,
                &text,
                &mut opts.overrides,
                opts.accuracy,
                opts.accuracy_cache.as_deref(),
            )?;
            if let Some(pick) = &picked {
                tracing::info!("{}", pick.reason());
            }
            let mut host = Hosted::load(text, scene.clone(), &opts)?;
            host.accuracy = picked.map(|p| p.reason());
            let journal = match &opts.journal {
                Some(path) => Some(Journal::create(path, &opts.world, &host, &opts)?),
                None => None,
            };
            Ok(Started {
                host,
                answered: Answered::default(),
                journal,
                opts,
            })
        }
    }
}
