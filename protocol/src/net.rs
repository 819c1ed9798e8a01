//! How every Ricochet process joins the network: the one set of network flags the
//! server, the viewer and the CLI share ([`NetworkArgs`]), the zenoh session they build
//! from it ([`Network::open`]), and the one tracing set-up ([`init_tracing`]).
//!
//! Flags (and optionally a zenoh configuration file, json5, the format of zenoh's own
//! tools) flow in; a configured zenoh session flows out.

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use zenoh::{Session, Wait};

/// The endpoint a server listens on, and clients connect to, when none is given.
pub const DEFAULT_ENDPOINT: &str = "tcp/127.0.0.1:7447";

/// How a zenoh session joins the network.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Talks directly to the peers it connects to or that connect to it.
    #[default]
    Peer,
    /// Talks only through the router it connects to.
    Client,
    /// Routes for others: where worlds on several hosts meet.
    Router,
}

impl Mode {
    /// The mode as zenoh's configuration spells it.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Peer => "peer",
            Mode::Client => "client",
            Mode::Router => "router",
        }
    }
}

/// Where a zenoh session connects and listens: the flags of every Ricochet binary
/// (global, so they may come before or after a subcommand).
/// The short flags are zenoh's own tools' (`-l`, `-e`, `-m`, `-c`).
#[derive(clap::Args, Clone, Debug, Default)]
#[command(next_help_heading = "Network")]
pub struct NetworkArgs {
    /// Endpoint to listen on, e.g. tcp/127.0.0.1:7447 or tcp/0.0.0.0:7447. Repeatable.
    #[arg(short, long, global = true, value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Endpoint of a peer or router to connect to, e.g. tcp/10.0.0.5:7447. Repeatable.
    #[arg(short = 'e', long, global = true, value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// peer (talk to peers directly; the default), client (only through a router) or
    /// router.
    #[arg(short, long, global = true, value_enum)]
    pub mode: Option<Mode>,
    /// Also discover peers by multicast scouting (off: explicit endpoints only).
    #[arg(long, global = true)]
    pub multicast: bool,
    /// A zenoh configuration file (json5, as zenoh's own tools read): credentials, TLS,
    /// access control, anything zenoh offers. The flags given are merged over it; with a
    /// file, nothing else is assumed (no default endpoint, mode or scouting), so the file
    /// says how to connect. See assets/zenoh/ and docs/security.md.
    #[arg(short, long, global = true, value_name = "FILE")]
    pub config: Option<PathBuf>,
}

impl NetworkArgs {
    /// A server's network: with no endpoint given (and no configuration file), listen on
    /// the default one.
    pub fn server(self) -> Network {
        let listen = if self.listen.is_empty() && self.connect.is_empty() && self.config.is_none() {
            vec![DEFAULT_ENDPOINT.to_string()]
        } else {
            self.listen
        };
        Network {
            mode: self.mode,
            connect: self.connect,
            listen,
            multicast: self.multicast,
            config: self.config,
        }
    }

    /// A client's network: with no endpoint given (and no configuration file), connect to
    /// the default one.
    pub fn client(self) -> Network {
        let connect = if self.listen.is_empty() && self.connect.is_empty() && self.config.is_none()
        {
            vec![DEFAULT_ENDPOINT.to_string()]
        } else {
            self.connect
        };
        Network {
            mode: self.mode,
            connect,
            listen: self.listen,
            multicast: self.multicast,
            config: self.config,
        }
    }
}

/// The largest message a client or a router takes, in bytes: above the largest a server
/// sends (a key frame of a world at its limits, 2 000 000 particles and 100 000 bodies, is
/// about 25 MB; a statics snapshot of 100 000 bodies about 4 MB), far below zenoh's
/// default of 1 GiB.
pub const MAX_MESSAGE_BYTES: usize = 64 << 20;

/// Sessions a server or router takes at most, in all (zenoh's default is 1000).
pub const MAX_SESSIONS: usize = 256;

/// Links a listening process keeps waiting in zenoh's handshake at once (zenoh's default
/// is 100): past it, a new link is closed at once. A process holding 300 links that never
/// send the handshake kept every honest session out under the default.
pub const ACCEPT_PENDING: usize = 1024;

/// How long a link may take to finish zenoh's handshake, in milliseconds (zenoh's default
/// is 10 000): an honest one on loopback takes a few, over TLS a few round trips. A link
/// that never sends it holds a place in [`ACCEPT_PENDING`] this long.
pub const ACCEPT_TIMEOUT_MS: u64 = 2_000;

/// Where and how a session connects.
#[derive(Clone, Debug, Default)]
pub struct Network {
    /// The mode; `None` is peer, or the configuration file's.
    pub mode: Option<Mode>,
    /// Endpoints to connect to (`tcp/host:port`).
    pub connect: Vec<String>,
    /// Endpoints to listen on.
    pub listen: Vec<String>,
    /// Multicast scouting (off by default: explicit endpoints only).
    pub multicast: bool,
    /// A zenoh configuration file (json5) the rest is merged over.
    pub config: Option<PathBuf>,
}

impl Network {
    /// A client's network: connect to `connect`, or to the default endpoint.
    pub fn client(mode: Mode, connect: Vec<String>) -> Self {
        NetworkArgs {
            mode: Some(mode),
            connect,
            ..NetworkArgs::default()
        }
        .client()
    }

    /// Where this network reaches, for a message: its endpoints, or the configuration
    /// file that says.
    pub fn endpoints_described(&self) -> String {
        match (&self.config, self.connect.is_empty()) {
            (_, false) => self.connect.join(", "),
            (Some(file), true) => format!("the endpoints of {}", file.display()),
            (None, true) => "no endpoint".to_string(),
        }
    }

    /// The mode's name for logs: as given, or the file's, or peer.
    pub fn mode_name(&self) -> &'static str {
        match (self.mode, &self.config) {
            (Some(mode), _) => mode.name(),
            (None, Some(_)) => "from the configuration file",
            (None, None) => Mode::Peer.name(),
        }
    }

    /// The zenoh configuration: the file's (or zenoh's defaults), then the flags. Without
    /// a file, Ricochet's defaults: peer mode, no multicast scouting, endpoints retried
    /// until they come up. With one, only what was given overrides it.
    pub fn config(&self) -> Result<zenoh::Config> {
        let mut config = match &self.config {
            Some(path) => zenoh::Config::from_file(path)
                .map_err(|e| anyhow!("zenoh configuration file {}: {e}", path.display()))?,
            None => zenoh::Config::default(),
        };
        let defaults = self.config.is_none();
        let set = |config: &mut zenoh::Config, key: &str, value: serde_json::Value| {
            config
                .insert_json5(key, &value.to_string())
                .map_err(|e| anyhow!("zenoh configuration {key} = {value}: {e}"))
        };
        match self.mode {
            Some(mode) => set(&mut config, "mode", serde_json::json!(mode.name()))?,
            None if defaults => set(&mut config, "mode", serde_json::json!("peer"))?,
            None => {}
        }
        if defaults || !self.connect.is_empty() {
            set(
                &mut config,
                "connect/endpoints",
                serde_json::json!(self.connect),
            )?;
        }
        if defaults || !self.listen.is_empty() {
            set(
                &mut config,
                "listen/endpoints",
                serde_json::json!(self.listen),
            )?;
        }
        if defaults || self.multicast {
            set(
                &mut config,
                "scouting/multicast/enabled",
                serde_json::json!(self.multicast),
            )?;
        }
        if defaults {
            // Keep retrying a connect endpoint that is not up yet, so a client may start
            // before its server or router.
            set(&mut config, "connect/timeout_ms", serde_json::json!(-1))?;
            // No peer makes a client or a router buffer more than the largest message a
            // server sends (zenoh's default is 1 GiB); a server bounds its own lower.
            set(
                &mut config,
                "transport/link/rx/max_message_size",
                serde_json::json!(MAX_MESSAGE_BYTES),
            )?;
            // Sessions a listening process takes at most, in all (zenoh's default is
            // 1000): a bound on what peers can make it hold. Per address, the operator's
            // firewall bounds them (docs/security.md), which zenoh cannot.
            set(
                &mut config,
                "transport/unicast/max_sessions",
                serde_json::json!(MAX_SESSIONS),
            )?;
            // Links held in the handshake: a bound high enough that one process must open
            // more than ACCEPT_PENDING links every ACCEPT_TIMEOUT_MS to keep a new session
            // out, and a timeout short enough that what it holds is soon let go.
            set(
                &mut config,
                "transport/unicast/accept_pending",
                serde_json::json!(ACCEPT_PENDING),
            )?;
            set(
                &mut config,
                "transport/unicast/accept_timeout",
                serde_json::json!(ACCEPT_TIMEOUT_MS),
            )?;
        }
        Ok(config)
    }

    /// Opens the session.
    pub fn open(&self) -> Result<Session> {
        self.open_with(self.config()?)
    }

    /// Opens the session under `identity`'s zenoh id (whatever the configuration file
    /// says), so the messages it signs prove their sender ([`crate::identity`]).
    pub fn open_as(&self, identity: &crate::identity::Identity) -> Result<Session> {
        let mut config = self.config()?;
        config
            .insert_json5("id", &serde_json::json!(identity.zid()).to_string())
            .map_err(|e| anyhow!("zenoh configuration id = {}: {e}", identity.zid()))?;
        self.open_with(config)
    }

    fn open_with(&self, config: zenoh::Config) -> Result<Session> {
        zenoh::open(config).wait().map_err(|e| {
            anyhow!(
                "cannot open a zenoh session ({} mode, connect {:?}, listen {:?}{}): {e}",
                self.mode_name(),
                self.connect,
                self.listen,
                self.config
                    .as_ref()
                    .map(|p| format!(", configuration {}", p.display()))
                    .unwrap_or_default()
            )
        })
    }
}

/// What a binary's `completions SHELL` and `man` commands print: shell completions for
/// `command`, or its manual page (roff), generated from its flags.
#[derive(clap::Subcommand, Clone, Debug)]
pub enum SelfDoc {
    /// Print shell completions, e.g. `completions bash > /etc/bash_completion.d/NAME`.
    Completions {
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Print the manual page (roff), e.g. `man > NAME.1 && man ./NAME.1`.
    Man,
}

impl SelfDoc {
    /// Writes what was asked for `command` (the binary's whole command line) to `out`.
    pub fn write(
        &self,
        mut command: clap::Command,
        out: &mut dyn std::io::Write,
    ) -> anyhow::Result<()> {
        match self {
            SelfDoc::Completions { shell } => {
                let name = command.get_name().to_string();
                clap_complete::generate(*shell, &mut command, name, out);
            }
            SelfDoc::Man => clap_mangen::Man::new(command).render(out)?,
        }
        Ok(())
    }
}

/// How much a binary logs: `-v` for more, `-q` for less (global flags of every binary).
#[derive(clap::Args, Clone, Copy, Debug, Default)]
#[command(next_help_heading = "Logging")]
pub struct Verbosity {
    /// Log more: -v adds Ricochet's debug lines, -vv its trace lines and other crates'
    /// debug lines. Overrides RUST_LOG.
    #[arg(short, long, global = true, action = clap::ArgAction::Count, conflicts_with = "quiet")]
    pub verbose: u8,
    /// Log less: -q keeps warnings and errors, -qq errors only, -qqq nothing.
    /// Overrides RUST_LOG.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub quiet: u8,
}

impl Verbosity {
    /// Levels to move from the default: above 0 more, below 0 less.
    fn shift(self) -> i32 {
        i32::from(self.verbose) - i32::from(self.quiet)
    }
}

/// The targets of Ricochet's own crates and binaries, which `-v` opens up.
const OWN_TARGETS: [&str; 6] = [
    "ricochet",
    "ricochet_engine",
    "ricochet_protocol",
    "ricochet_server",
    "ricochet_viewer",
    "ricochet_lab",
];

/// Log levels from quietest to loudest, as tracing's filters spell them.
const LEVELS: [&str; 6] = ["off", "error", "warn", "info", "debug", "trace"];

fn rank(level: &str) -> Result<usize> {
    LEVELS
        .iter()
        .position(|l| l.eq_ignore_ascii_case(level))
        .ok_or_else(|| anyhow!("`{level}` is not a log level"))
}

/// The filter `default_filter` (`"LEVEL,target=LEVEL,..."`) becomes under `shift`
/// (`-v` counts up, `-q` down): -v logs Ricochet's own targets at debug, -vv at trace and
/// every other crate at debug; -q caps every level at warn, -qq at error, -qqq at off.
pub fn shifted_filter(default_filter: &str, shift: i32) -> Result<String> {
    let info = rank("info")? as i32;
    let at = LEVELS[(info + shift).clamp(0, LEVELS.len() as i32 - 1) as usize];
    let mut base = "info";
    let mut directives = Vec::new();
    for part in default_filter.split(',').filter(|p| !p.is_empty()) {
        match part.split_once('=') {
            Some((target, level)) => directives.push((target, level)),
            None => base = part,
        }
    }
    rank(base)?;
    let capped =
        |level: &'static str| -> Result<&'static str> { Ok(LEVELS[rank(level)?.min(rank(at)?)]) };
    let filter: Vec<String> = match shift {
        0 => return Ok(default_filter.to_string()),
        1 => std::iter::once(base.to_string())
            .chain(directives.iter().map(|(t, l)| format!("{t}={l}")))
            .chain(OWN_TARGETS.iter().map(|t| format!("{t}={at}")))
            .collect(),
        s if s > 1 => std::iter::once("debug".to_string())
            .chain(OWN_TARGETS.iter().map(|t| format!("{t}={at}")))
            .collect(),
        _ => {
            let mut filter = vec![LEVELS[rank(base)?.min(rank(at)?)].to_string()];
            for (t, l) in &directives {
                let level = LEVELS[rank(l)?];
                filter.push(format!("{t}={}", capped(level)?));
            }
            filter
        }
    };
    Ok(filter.join(","))
}

/// Logs to standard error, filtered by `default_filter` (e.g. `"info,zenoh=warn"`) moved
/// by `-v`/`-q`; with neither flag, `RUST_LOG` when it is set. Call once, first thing in
/// `main`, with the flags parsed.
pub fn init_tracing(default_filter: &str, verbosity: Verbosity) {
    use std::io::IsTerminal;
    let filter = match verbosity.shift() {
        0 => tracing_subscriber::EnvFilter::try_from_default_env()
            .unwrap_or_else(|_| default_filter.into()),
        shift => match shifted_filter(default_filter, shift) {
            Ok(filter) => filter.into(),
            // The defaults are the binaries' own constants; one that does not parse is a
            // bug, said here rather than silencing every log.
            Err(e) => panic!("default log filter `{default_filter}`: {e}"),
        },
    };
    let described = filter.to_string();
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        // Colour only for a person at a terminal: a log file or a pipe gets plain text.
        .with_ansi(std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none())
        .init();
    tracing::debug!(filter = %described, "logging");
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Flags {
        #[command(flatten)]
        net: NetworkArgs,
    }

    fn flags(args: &[&str]) -> NetworkArgs {
        Flags::try_parse_from(std::iter::once("x").chain(args.iter().copied()))
            .unwrap_or_else(|e| panic!("{e}"))
            .net
    }

    #[test]
    fn verbosity_moves_the_default_filter() {
        assert_eq!(
            shifted_filter("info,zenoh=warn", 0).unwrap(),
            "info,zenoh=warn"
        );
        let louder = shifted_filter("warn,zenoh=error", 1).unwrap();
        assert!(
            louder.starts_with("warn,zenoh=error,ricochet=debug,"),
            "{louder}"
        );
        assert!(louder.ends_with("ricochet_lab=debug"), "{louder}");
        let loudest = shifted_filter("warn,zenoh=error", 2).unwrap();
        assert!(loudest.starts_with("debug,ricochet=trace,"), "{loudest}");
        let quieter = shifted_filter("info,zenoh=warn,re_chunk=error", -1).unwrap();
        assert_eq!(quieter, "warn,zenoh=warn,re_chunk=error");
        assert_eq!(
            shifted_filter("warn,zenoh=error", -5).unwrap(),
            "off,zenoh=off"
        );
        assert!(shifted_filter("loud", 1).is_err());
        let flags = |args: &[&str]| {
            #[derive(Parser)]
            struct Flags {
                #[command(flatten)]
                verbosity: Verbosity,
            }
            Flags::try_parse_from(std::iter::once("x").chain(args.iter().copied()))
                .map(|f| f.verbosity.shift())
        };
        assert_eq!(flags(&["-vv"]).unwrap(), 2);
        assert_eq!(flags(&["-q"]).unwrap(), -1);
        assert!(
            flags(&["-v", "-q"]).is_err(),
            "-v and -q together are refused"
        );
    }

    #[test]
    fn servers_listen_and_clients_connect_on_the_default_endpoint() {
        let server = flags(&[]).server();
        assert_eq!(server.listen, [DEFAULT_ENDPOINT]);
        assert!(server.connect.is_empty());
        let client = flags(&[]).client();
        assert_eq!(client.connect, [DEFAULT_ENDPOINT]);
        assert!(client.listen.is_empty());
    }

    #[test]
    fn clients_and_routers_bound_what_a_peer_makes_them_buffer() {
        let key = "transport/link/rx/max_message_size";
        let ours = |config: &zenoh::Config| config.get_json(key).unwrap();
        for net in [flags(&[]).client(), flags(&["--mode", "router"]).server()] {
            assert_eq!(ours(&net.config().unwrap()), MAX_MESSAGE_BYTES.to_string());
        }
        assert_ne!(
            ours(&zenoh::Config::default()),
            MAX_MESSAGE_BYTES.to_string(),
            "zenoh's own default is larger"
        );
        // The secured deployment's files say the same.
        for role in ["client", "viewer", "router"] {
            let file = format!(
                "{}/../assets/zenoh/{role}.json5",
                env!("CARGO_MANIFEST_DIR")
            );
            let config = zenoh::Config::from_file(&file).unwrap();
            assert_eq!(ours(&config), MAX_MESSAGE_BYTES.to_string(), "{role}.json5");
        }
    }

    #[test]
    fn flags_override_the_defaults() {
        let n = flags(&["--mode", "client", "--connect", "tcp/10.0.0.5:7447"]).server();
        assert_eq!(n.mode, Some(Mode::Client));
        assert!(n.listen.is_empty());
        assert_eq!(n.connect, ["tcp/10.0.0.5:7447"]);
        let e = Flags::try_parse_from(["x", "--mode", "satellite"])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("satellite"), "{e}");
    }

    #[test]
    fn a_configuration_file_is_read_and_only_given_flags_override_it() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("z.json5");
        std::fs::write(
            &file,
            r#"{ mode: "client", connect: { endpoints: ["tcp/127.0.0.1:9"] },
                 scouting: { multicast: { enabled: false } } }"#,
        )
        .unwrap();
        let path = file.to_str().unwrap();
        let n = flags(&["--config", path]).client();
        assert!(n.connect.is_empty(), "no default endpoint with a file");
        let c = n.config().unwrap();
        assert_eq!(c.get_json("mode").unwrap(), "\"client\"");
        assert_eq!(
            c.get_json("connect/endpoints").unwrap(),
            r#"["tcp/127.0.0.1:9"]"#
        );
        let n = flags(&["--config", path, "--connect", "tcp/127.0.0.1:10"]).client();
        let c = n.config().unwrap();
        assert_eq!(
            c.get_json("connect/endpoints").unwrap(),
            r#"["tcp/127.0.0.1:10"]"#
        );
        std::fs::write(&file, "{ mode: ").unwrap();
        let e = flags(&["--config", path]).client().config().unwrap_err();
        assert!(e.to_string().contains("z.json5"), "{e}");
    }
}

/// A link's rate in bits a second, from `5000000`, `5M`, `5Mbit`, `500k`, `500kbit`,
/// `1.5G` (k, M and G are powers of 1000; a trailing `bit`, `bps` or `b/s` is allowed).
pub fn parse_bits_per_second(text: &str) -> Result<f64, String> {
    let t = text.trim();
    let t = ["bit/s", "bps", "b/s", "bit"]
        .iter()
        .find_map(|unit| t.strip_suffix(unit))
        .unwrap_or(t);
    let (number, scale) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('M') => (&t[..t.len() - 1], 1e6),
        Some('G') => (&t[..t.len() - 1], 1e9),
        _ => (t, 1.0),
    };
    match number.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v * scale),
        _ => Err(format!(
            "`{}` is not a rate: give bits a second, as 5000000, 5M, 5Mbit or 500kbit",
            crate::text::short(text, 40)
        )),
    }
}

#[cfg(test)]
mod rate_tests {
    use super::parse_bits_per_second as parse;

    #[test]
    fn rates_read_with_their_units() {
        assert_eq!(parse("5000000"), Ok(5e6));
        assert_eq!(parse("5M"), Ok(5e6));
        assert_eq!(parse("5Mbit"), Ok(5e6));
        assert_eq!(parse("500kbit"), Ok(5e5));
        assert_eq!(parse("1.5G"), Ok(1.5e9));
        assert_eq!(parse("2 Mbps"), Ok(2e6));
        for bad in ["", "fast", "-5M", "0", "NaNM", "5T"] {
            assert!(parse(bad).is_err(), "{bad}");
        }
    }
}
