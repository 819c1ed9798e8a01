//! Key expressions of a world named `<world>`:
//!
//! | key | kind | payload |
//! |---|---|---|
//! | `ricochet/<world>/cmd` | subscriber (server) | a command, JSON, fire and forget |
//! | `ricochet/<world>/rpc` | queryable (server) | a command, JSON; the reply is a [`crate::command::Reply`] |
//! | `ricochet/<world>/frame` | publication, every step | a binary frame ([`crate::frame`]) |
//! | `ricochet/<world>/snapshot` | publication when statics change, and queryable | a binary snapshot of the static bodies |
//! | `ricochet/<world>/state` | queryable | a key frame of the dynamic state now, for late joiners |
//! | `ricochet/<world>/info` | queryable | a [`crate::command::WorldInfo`], JSON: the scene's name, bounds, step and groups |
//! | `ricochet/<world>/event` | publication | a [`crate::command::Event`] per handled command, JSON |
//! | `ricochet/<world>/alive/<zid>` | liveliness token | held while the server runs; `<zid>` is its zenoh id |
//!
//! Clients take a reply only from the zenoh instance whose id the world's token names (see
//! [`crate::client`]), so a stray queryable on a world's keys is not taken for its server.
//!
//! A world name is 1 to 64 characters of `A-Z a-z 0-9 _ -`.

/// The root of every key.
pub const ROOT: &str = "ricochet";

/// The world a server hosts when none is named.
pub const DEFAULT_WORLD: &str = "default";

/// The frame streams a server publishes, by the steps a frame of each stands for: every
/// step, and reduced-rate tiers for viewers whose link cannot carry every step.
pub const STREAMS: [u64; 4] = [1, 2, 4, 8];

/// Checks a world name.
pub fn check_world(name: &str) -> Result<(), String> {
    if name.is_empty() || name.len() > 64 {
        return Err(format!("world name `{name}` must be 1 to 64 characters"));
    }
    if let Some(c) = name
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
    {
        return Err(format!(
            "world name `{name}` has `{c}`: use A-Z a-z 0-9 _ -"
        ));
    }
    Ok(())
}

/// The keys of one world.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorldKeys {
    pub world: String,
    pub cmd: String,
    pub rpc: String,
    pub frame: String,
    pub snapshot: String,
    pub state: String,
    pub info: String,
    pub event: String,
    /// `ricochet/<world>/alive`: the prefix of the world's liveliness token.
    pub alive: String,
}

impl WorldKeys {
    pub fn new(world: &str) -> Result<Self, String> {
        check_world(world)?;
        let k = |leaf: &str| format!("{ROOT}/{world}/{leaf}");
        Ok(WorldKeys {
            world: world.to_string(),
            cmd: k("cmd"),
            rpc: k("rpc"),
            frame: k("frame"),
            snapshot: k("snapshot"),
            state: k("state"),
            info: k("info"),
            event: k("event"),
            alive: k("alive"),
        })
    }

    /// The frames of the stream that carries one step in `every` (`frame` for every
    /// step, `frame/<every>` for a reduced-rate tier).
    pub fn frame_every(&self, every: u64) -> String {
        match every {
            1 => self.frame.clone(),
            n => format!("{}/{n}", self.frame),
        }
    }

    /// The state query of that stream: a key frame of what its receivers hold.
    pub fn state_every(&self, every: u64) -> String {
        match every {
            1 => self.state.clone(),
            n => format!("{}/{n}", self.state),
        }
    }

    /// The liveliness token a server with zenoh id `zid` declares for this world.
    pub fn alive_token(&self, zid: &str) -> String {
        format!("{}/{zid}", self.alive)
    }

    /// The key expression matching every token of this world (normally exactly one).
    pub fn alive_tokens(&self) -> String {
        format!("{}/*", self.alive)
    }
}

/// The liveliness key expression matching every world's token.
pub const ALL_ALIVE: &str = "ricochet/*/alive/*";

/// The world and the server's zenoh id named by a liveliness token's key,
/// `ricochet/<world>/alive/<zid>`.
pub fn parse_alive(key: &str) -> Option<(&str, &str)> {
    let rest = key.strip_prefix("ricochet/")?;
    let (world, zid) = rest.split_once("/alive/")?;
    (!world.contains('/') && !zid.is_empty() && !zid.contains('/')).then_some((world, zid))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_of_a_world() {
        let k = WorldKeys::new("arena-2").unwrap();
        assert_eq!(k.frame, "ricochet/arena-2/frame");
        assert_eq!(
            parse_alive(&k.alive_token("a1b2")),
            Some(("arena-2", "a1b2"))
        );
        assert_eq!(parse_alive(&k.alive), None);
        assert_eq!(parse_alive("ricochet/a/b/alive/z"), None);
        assert!(WorldKeys::new("a/b").is_err());
        assert!(WorldKeys::new("*").is_err());
        assert!(WorldKeys::new("").is_err());
    }
}
