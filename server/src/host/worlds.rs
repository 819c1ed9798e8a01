//! The worlds one server serves: its own, and the forks `fork` starts from it. Each is a
//! world of its own on the same zenoh session: its own keys (`ricochet/<name>/...`),
//! thread, clock, budgets and limits, listed by `ricochet worlds` like any other, and
//! stopped by `close`. A fork is not journaled: it lives as long as the server does.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use anyhow::anyhow;
use ricochet_protocol::command::{Action, Command, ServerCommand};
use ricochet_protocol::keys::WorldKeys;
use ricochet_protocol::text::short;

use super::answered::Answered;
use super::hosted::{Handled, Hosted};
use super::serve::Serving;
use super::start::Started;
use super::wiring::Wiring;
use super::HostOptions;

/// Settings a `fork` may name at most.
pub const MAX_FORK_SETTINGS: usize = 32;

/// The worlds served here, by name, each with the flag that stops it.
pub struct Worlds {
    session: zenoh::Session,
    /// The options every world here runs under (the server's).
    opts: HostOptions,
    served: Mutex<BTreeMap<String, Arc<AtomicBool>>>,
    /// The signal that stops the server (SIGTERM, SIGINT): every world here stops on it.
    signal: Arc<AtomicUsize>,
}

/// One world's place among the [`Worlds`]: its name and the flag that stops it.
pub struct Slot {
    pub worlds: Arc<Worlds>,
    pub name: String,
    pub stop: Arc<AtomicBool>,
}

impl Drop for Slot {
    fn drop(&mut self) {
        let mut served = self.worlds.served.lock().expect("the worlds' lock");
        if served
            .get(&self.name)
            .is_some_and(|s| Arc::ptr_eq(s, &self.stop))
        {
            served.remove(&self.name);
        }
    }
}

impl Worlds {
    /// The worlds of a server whose own world is `opts.world`, on `session`.
    pub fn new(
        session: zenoh::Session,
        opts: &HostOptions,
        signal: Arc<AtomicUsize>,
    ) -> (Arc<Worlds>, Slot) {
        let worlds = Arc::new(Worlds {
            session,
            opts: opts.clone(),
            served: Mutex::new(BTreeMap::new()),
            signal,
        });
        let slot = worlds
            .register(&opts.world)
            .expect("the first world has its name");
        (worlds, slot)
    }

    fn register(self: &Arc<Self>, name: &str) -> Result<Slot, String> {
        let mut served = self.served.lock().expect("the worlds' lock");
        if served.contains_key(name) {
            return Err(format!(
                "`world`: `{}` is served here already",
                short(name, 64)
            ));
        }
        if served.len() >= self.opts.max_worlds {
            return Err(format!(
                "`world`: this server serves {} worlds, its most (`run --max-worlds`); close a fork first",
                served.len()
            ));
        }
        let stop = Arc::new(AtomicBool::new(false));
        served.insert(name.to_string(), Arc::clone(&stop));
        Ok(Slot {
            worlds: Arc::clone(self),
            name: name.to_string(),
            stop,
        })
    }

    /// The names of the worlds served here.
    pub fn names(&self) -> Vec<String> {
        self.served
            .lock()
            .expect("the worlds' lock")
            .keys()
            .cloned()
            .collect()
    }
}

impl Slot {
    /// Whether `close` asked this world to stop.
    pub fn stopping(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Handles `fork` and `close` for the world in this slot (`host`).
    pub fn handle(&self, host: &mut Hosted, command: &ServerCommand) -> Handled {
        let frame = host.world.frame();
        let result = match command {
            ServerCommand::Fork { world, settings } => self.fork(host, world, settings),
            ServerCommand::Close if host.forked_from.is_none() => Err(format!(
                "`{}` is the server's own world: it stops with the server; `close` stops a fork",
                short(&self.name, 64)
            )),
            ServerCommand::Close => {
                self.stop.store(true, Ordering::Relaxed);
                tracing::info!(world = %self.name, frame, "closed");
                Ok(())
            }
            _ => Err("not a command of the worlds".to_string()),
        };
        match result {
            Ok(()) => host.accepted(frame),
            Err(e) => host.refuse(&e),
        }
    }

    /// Starts the fork `name` of `host` at its frame, with `settings` applied to it.
    fn fork(
        &self,
        host: &Hosted,
        name: &str,
        settings: &BTreeMap<String, serde_json::Value>,
    ) -> Result<(), String> {
        let keys = WorldKeys::new(name).map_err(|e| format!("`world`: {e}"))?;
        if settings.len() > MAX_FORK_SETTINGS {
            return Err(format!(
                "`settings`: {} settings; a fork takes at most {MAX_FORK_SETTINGS}",
                settings.len()
            ));
        }
        let mut world = host.world.clone();
        let mut overrides = host.source.overrides.clone();
        for (setting, value) in settings {
            let set = Action::Set {
                name: setting.clone(),
                value: value.clone(),
            };
            let checked = Command::from_value(
                serde_json::to_value(Command::World(set)).map_err(|e| e.to_string())?,
            )
            .map_err(|e| format!("`settings`: {e}"))?;
            let Command::World(set) = checked else {
                unreachable!("a set reads as a world action")
            };
            let action = crate::wire::to_engine(&set).map_err(|e| format!("`settings`: {e}"))?;
            world
                .apply(&action)
                .map_err(|e| format!("`settings.{}`: {e}", short(setting, 64)))?;
            overrides.push(format!("{setting}={value}"));
        }
        let slot = self.worlds.register(name)?;
        let mut opts = self.worlds.opts.clone();
        opts.world = name.to_string();
        opts.overrides = overrides;
        opts.journal = None;
        opts.resume = None;
        opts.dump = None;
        opts.max_frames = None;
        let mut fork = Hosted::with_world(
            world,
            host.source.text.clone(),
            host.source.name.clone(),
            &opts,
        );
        fork.forked_from = Some(self.name.clone());
        fork.stepping.paused = host.stepping.paused;
        fork.accuracy = host.accuracy.clone();
        let (wiring, publisher) = Wiring::declare(&self.worlds.session, &keys, &fork, &opts)
            .map_err(|e| format!("the fork's keys: {e:#}"))?;
        let started = Started {
            host: fork,
            answered: Answered::default(),
            journal: None,
            opts,
        };
        let serving =
            Serving::new(started, wiring, publisher, Arc::clone(&self.worlds.signal)).in_slot(slot);
        std::thread::Builder::new()
            .name(format!("world {}", short(name, 32)))
            .spawn(move || {
                if let Err(e) = serving.run() {
                    tracing::error!("a fork stopped: {e:#}");
                }
            })
            .map_err(|e| anyhow!("cannot start the fork's thread: {e}"))
            .map_err(|e| e.to_string())?;
        tracing::info!(world = %name, from = %self.name, frame = host.world.frame(), "forked");
        Ok(())
    }
}
