//! `ricochet`: the command-line client of a Ricochet world.
//!
//! Sends commands, plays scripts, watches frames, lists worlds, records and replays input
//! logs, over zenoh.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use clap::{Parser, Subcommand};
use ricochet_protocol::client::{list_worlds, parse_event, Client};
use ricochet_protocol::command::{parse_input_log, Command, ServerCommand, TimedAction};
use ricochet_protocol::frame::peek_header;
use ricochet_protocol::keys::DEFAULT_WORLD;
use ricochet_protocol::net::{init_tracing, Network, NetworkArgs, Verbosity};
use ricochet_protocol::text::short;

#[derive(Parser)]
#[command(
    name = "ricochet",
    version = ricochet_protocol::VERSION,
    about = "Command-line client of a Ricochet world",
    long_about = "Command-line client of a Ricochet world.\n\n\
A command is JSON ({\"do\": \"fire_dye_pack\", \"at\": [50, 60]}) or the short form\n\
`fire_dye_pack at=[50,60]`: the command's name, then NAME=VALUE arguments whose values\n\
are JSON (a bare word is a string).\n\n\
World commands: press/release dir=up|down|left|right, fire_dye_pack at=[x,y],\n\
spawn_minion at=[x,y] [shape=rect], spawn_dumb_minion at=[x,y], select at=[x,y] [group=G],\n\
drag to=[x,y], deselect, agitate [strength=S], clear group=G,\n\
spawn_particles preset=fire at=[x,y] [count=N], start_emitter preset=fire count=N at=[x,y],\n\
set name=NAME value=VALUE.\n\n\
Any body of any scene: spawn body={\"shape\":\"circle\",\"radius\":1,\"pos\":[x,y],...}\n\
(a scene's [[body]] fields) | spawn template=NAME at=[x,y] [vel=[x,y]], remove body=ID,\n\
impulse body=ID impulse=[x,y], set_body body=ID [pos=[x,y]] [vel=[x,y]];\n\
bodies [ids=[\"ID\",...]] [within=[[x0,y0],[x1,y1]]] replies with their state.\n\n\
Time: save name=N, restore name=N, rewind frame=F, hashes [from=F] [to=F] (each frame's\n\
state hash), fork world=NAME [settings={\"substeps\":4}] (a second world from this frame),\n\
close (stops a fork).\n\n\
Server commands: pause, resume, step [n=N], reset [paused=true],\n\
load path=NAME (a scene file under the server's scenes directory) | text=TOML."
)]
struct Cli {
    /// The world to talk to.
    #[arg(long, global = true, default_value = DEFAULT_WORLD)]
    world: String,
    #[command(flatten)]
    network: NetworkArgs,
    #[command(flatten)]
    verbosity: Verbosity,
    /// How long to wait for a reply, in seconds.
    #[arg(long, global = true, default_value_t = 5.0)]
    timeout: f64,
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Send one command and print the reply (exit 1 if it was refused).
    Send {
        /// The command: JSON, or NAME [ARG=VALUE]...
        #[arg(required = true, num_args = 1.., allow_hyphen_values = true)]
        command: Vec<String>,
        /// Fire and forget: do not wait for a reply.
        #[arg(long)]
        no_reply: bool,
    },
    /// Play a script of timed commands.
    ///
    /// Each line is `@N COMMAND` (when the world reaches frame N, counted from the frame
    /// the script started at) or `+T COMMAND` (T seconds after the previous line). Lines
    /// starting with # are comments.
    Script {
        file: PathBuf,
        /// Stop at the first refused command.
        #[arg(long)]
        strict: bool,
    },
    /// Print a summary of every frame.
    Watch {
        /// Stop after this many frames.
        #[arg(long)]
        frames: Option<u64>,
        /// Stop after this many seconds.
        #[arg(long)]
        seconds: Option<f64>,
        /// Print each frame's bodies and figures as JSON.
        #[arg(long)]
        json: bool,
        /// Watch the fullest frame stream whose rate fits this link: bits a second, with
        /// an optional k, M or G (`5M`, `5Mbit`, `500kbit`). The server's reduced-rate
        /// streams carry one frame in 2, 4 or 8 steps.
        #[arg(long, value_name = "RATE", value_parser = ricochet_protocol::net::parse_bits_per_second)]
        max_bandwidth: Option<f64>,
    },
    /// List the worlds whose servers are up (exit 1, saying so, when none answers).
    Worlds,
    #[command(flatten)]
    Doc(ricochet_protocol::net::SelfDoc),
    /// Record the applied world commands as an input log (JSON Lines).
    Record {
        file: PathBuf,
        /// Stop after this many seconds (otherwise at Ctrl-C).
        #[arg(long)]
        seconds: Option<f64>,
    },
    /// Replay an input log: reset the world paused, then step to each command's frame and
    /// apply it. Replaying the same log against the same scene and seed gives the same
    /// frames, bit for bit.
    Replay {
        file: PathBuf,
        /// Step on until this frame after the last command.
        #[arg(long)]
        until: Option<u64>,
        /// Resume real time at the end (otherwise the world stays paused).
        #[arg(long)]
        resume: bool,
    },
}

/// Times `script` and `replay` send a request that got no answer (with the same id, so the
/// server applies it once) before they stop and say where.
const ATTEMPTS: u32 = 3;

/// How long `watch` waits for a frame before it asks the world whether it is paused.
const QUIET_BEFORE_ASKING: Duration = Duration::from_secs(2);

fn main() {
    // zenoh's own warnings (a scouting delay, say) are not the user's business here; the
    // client says what failed itself.
    let cli = Cli::parse();
    init_tracing("warn,zenoh=error", cli.verbosity);
    match run(cli) {
        Ok(code) => std::process::exit(code),
        Err(e) => {
            eprintln!("ricochet: {e:#}");
            std::process::exit(2);
        }
    }
}

/// Parses `NAME ARG=VALUE ...` or a JSON object into a command.
pub fn parse_command_words(words: &[String]) -> Result<Command> {
    let joined = words.join(" ");
    if joined.trim_start().starts_with('{') {
        return Command::parse(joined.as_bytes()).map_err(|e| anyhow!(e));
    }
    let mut object = serde_json::Map::new();
    object.insert("do".into(), serde_json::Value::String(words[0].clone()));
    for arg in &words[1..] {
        let (name, value) = arg
            .split_once('=')
            .ok_or_else(|| anyhow!("argument `{arg}` is not NAME=VALUE"))?;
        let value = serde_json::from_str(value)
            .unwrap_or_else(|_| serde_json::Value::String(value.to_string()));
        object.insert(name.to_string(), value);
    }
    Command::from_value(serde_json::Value::Object(object)).map_err(|e| anyhow!(e))
}

fn run(cli: Cli) -> Result<i32> {
    let network = cli.network.clone().client();
    let timeout = Duration::from_secs_f64(cli.timeout.max(0.01));
    match cli.command {
        Cmd::Doc(doc) => {
            use clap::CommandFactory;
            doc.write(Cli::command(), &mut std::io::stdout().lock())?;
            Ok(0)
        }
        Cmd::Worlds => {
            let session = network.open()?;
            let worlds = list_worlds(&session, timeout)?;
            if worlds.is_empty() {
                // Silence would read as "no worlds" and "no server" alike: say which.
                eprintln!(
                    "ricochet: no world answered within {:.1} s (is a server up, and reachable at {}?)",
                    timeout.as_secs_f64(),
                    network.endpoints_described()
                );
                return Ok(1);
            }
            for w in worlds {
                // A world's name is what a peer chose: printed with control characters
                // escaped, so it cannot drive the terminal.
                println!("{}", ricochet_protocol::text::short(&w, 256));
            }
            Ok(0)
        }
        Cmd::Send { command, no_reply } => {
            let command = parse_command_words(&command)?;
            let client = Client::open(&network, &cli.world)?;
            if no_reply {
                client.send(&command)?;
                // Give the session a moment to flush before it closes.
                std::thread::sleep(Duration::from_millis(200));
                return Ok(0);
            }
            let reply = client.request(&command, timeout)?;
            println!("{}", serde_json::to_string(&reply)?);
            Ok(if reply.ok { 0 } else { 1 })
        }
        Cmd::Script { file, strict } => script(&network, &cli.world, &file, strict, timeout),
        Cmd::Watch {
            frames,
            seconds,
            json,
            max_bandwidth,
        } => watch(&network, &cli.world, frames, seconds, json, max_bandwidth),
        Cmd::Record { file, seconds } => record(&network, &cli.world, &file, seconds),
        Cmd::Replay {
            file,
            until,
            resume,
        } => replay(&network, &cli.world, &file, until, resume, timeout),
    }
}

/// One line of a script.
enum When {
    Frame(u64),
    After(Duration),
}

fn parse_script(text: &str, file: &Path) -> Result<Vec<(When, Command, usize)>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let at = |msg: String| anyhow!("{}:{}: {msg}", file.display(), i + 1);
        let (when, rest) = line
            .split_once(char::is_whitespace)
            .ok_or_else(|| at("expected `@FRAME COMMAND` or `+SECONDS COMMAND`".into()))?;
        let when = if let Some(n) = when.strip_prefix('@') {
            When::Frame(
                n.parse()
                    .map_err(|_| at(format!("`{when}`: expected @FRAME, a whole number")))?,
            )
        } else if let Some(t) = when.strip_prefix('+') {
            let secs: f64 = t
                .trim_end_matches('s')
                .parse()
                .map_err(|_| at(format!("`{when}`: expected +SECONDS")))?;
            if !(0.0..=86_400.0).contains(&secs) {
                return Err(at(format!("`{when}`: seconds must be 0 to 86400")));
            }
            When::After(Duration::from_secs_f64(secs))
        } else {
            return Err(at(format!(
                "`{when}`: a line starts with @FRAME or +SECONDS"
            )));
        };
        let words: Vec<String> = if rest.trim_start().starts_with('{') {
            vec![rest.trim().to_string()]
        } else {
            rest.split_whitespace().map(str::to_string).collect()
        };
        let command = parse_command_words(&words).map_err(|e| at(e.to_string()))?;
        out.push((when, command, i + 1));
    }
    Ok(out)
}

fn script(
    network: &Network,
    world: &str,
    file: &Path,
    strict: bool,
    timeout: Duration,
) -> Result<i32> {
    let text =
        std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    let lines = parse_script(&text, file)?;
    let client = Client::open(network, world)?;
    let mut clock = FrameClock {
        frames: client.frames()?,
        current: None,
    };
    let start = clock.poll(Some(timeout))?.ok_or_else(|| {
        anyhow!("no frames from world `{world}` within {timeout:?}: is its server up?")
    })?;
    let mut refused = 0;
    for (when, command, line) in lines {
        match when {
            When::After(d) => std::thread::sleep(d),
            When::Frame(n) => {
                let target = start + n;
                let mut progress = (Instant::now(), clock.current);
                while clock
                    .poll(Some(Duration::from_millis(100)))?
                    .is_none_or(|f| f < target)
                {
                    if clock.current != progress.1 {
                        progress = (Instant::now(), clock.current);
                    } else if progress.0.elapsed() > timeout {
                        bail!("line {line}: the world stopped at frame {:?} before frame {target} (paused?)", clock.current);
                    }
                }
            }
        }
        let reply = client
            .request_retrying(&command, timeout, ATTEMPTS)
            .with_context(|| {
                format!(
                    "line {line}: no answer to {} after {ATTEMPTS} attempts; the lines before it were applied, this one and those after it were not",
                    short(&command.to_json(), 80)
                )
            })?;
        println!(
            "{}: {} -> {}",
            line,
            command.to_json(),
            serde_json::to_string(&reply)?
        );
        if !reply.ok {
            refused += 1;
            if strict {
                return Ok(1);
            }
        }
    }
    Ok(if refused > 0 && strict { 1 } else { 0 })
}

/// The latest frame number seen on a world's frame stream.
struct FrameClock {
    frames: ricochet_protocol::client::FrameStream,
    current: Option<u64>,
}

impl FrameClock {
    /// Drains the stream (waiting up to `block` for the first frame) and returns the
    /// latest frame number seen so far.
    fn poll(&mut self, block: Option<Duration>) -> Result<Option<u64>> {
        let first = match block {
            Some(t) => self.frames.recv_timeout(t).map_err(|e| anyhow!("{e}"))?,
            None => self.frames.try_recv().map_err(|e| anyhow!("{e}"))?,
        };
        let mut next = first;
        while let Some(sample) = next {
            if let Ok(h) = peek_header(&sample.payload().to_bytes()) {
                self.current = Some(h.frame);
            }
            next = self.frames.try_recv().map_err(|e| anyhow!("{e}"))?;
        }
        Ok(self.current)
    }
}

fn watch(
    network: &Network,
    world: &str,
    frames: Option<u64>,
    seconds: Option<f64>,
    json: bool,
    max_bandwidth: Option<f64>,
) -> Result<i32> {
    let mut client = Client::open(network, world)?;
    if let Some(bits) = max_bandwidth {
        let every = client.watch_within(bits, Duration::from_secs(5))?;
        tracing::info!(every, "watching the stream of one frame in {every} steps");
    }
    let (stream, mut decoder) = client.join(Duration::from_secs(5))?;
    let began = Instant::now();
    let limit = seconds.map(Duration::from_secs_f64);
    let mut seen = 0u64;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let mut dropped_key_frames = 0;
    // A world that sends nothing is asked why, once a while: a paused world is said so
    // (silence would read as a hang).
    let mut last_frame = Instant::now();
    let mut said_paused = false;
    loop {
        if frames.is_some_and(|n| seen >= n) || limit.is_some_and(|l| began.elapsed() >= l) {
            return Ok(0);
        }
        let Some(sample) = stream
            .recv_timeout(Duration::from_millis(200))
            .map_err(|e| anyhow!("{e}"))?
        else {
            if !said_paused && last_frame.elapsed() >= QUIET_BEFORE_ASKING {
                last_frame = Instant::now();
                if let Ok(info) = client.info(Duration::from_secs(1)) {
                    if info.paused {
                        said_paused = true;
                        eprintln!(
                            "ricochet: world `{}` is paused at frame {} (send `resume`, or `step n=N`); waiting for frames",
                            short(world, 64).escape_debug(),
                            decoder.frame
                        );
                    }
                }
            }
            continue;
        };
        last_frame = Instant::now();
        said_paused = false;
        let bytes = sample.payload().to_bytes();
        match decoder.apply(&bytes) {
            Ok(h) => {
                seen += 1;
                if decoder.dropped_key_frames > dropped_key_frames {
                    dropped_key_frames = decoder.dropped_key_frames;
                    tracing::warn!(
                        dropped = dropped_key_frames,
                        "a key frame the stream did not follow was dropped"
                    );
                }
                let s = &h.stats;
                if json {
                    let bodies: Vec<_> = decoder
                        .bodies
                        .iter()
                        .map(|b| serde_json::json!({"id": b.id, "x": b.pos()[0], "y": b.pos()[1], "vx": b.vel()[0], "vy": b.vel()[1], "collided": b.collided}))
                        .collect();
                    let received_ms = std::time::SystemTime::now()
                        .duration_since(std::time::UNIX_EPOCH)
                        .map_or(0, |d| d.as_millis() as u64);
                    let line = serde_json::json!({
                        "frame": h.frame, "t": h.time, "bytes": bytes.len(), "key": h.kind == 1,
                        "every": client.every(), "received_ms": received_ms,
                        "bodies": bodies, "statics": decoder.statics.len(), "particles": decoder.particles.len(),
                        "emitters": decoder.emitters.len(), "contacts": s.contacts, "overruns": s.overruns,
                    });
                    writeln!(out, "{line}")?;
                } else {
                    writeln!(
                        out,
                        "frame {} t={:.3}s bodies {} statics {} particles {} emitters {} contacts {} relax {} deepest {:.4} ke {:.2} step {:.3}ms overruns {} bytes {}",
                        h.frame, h.time, decoder.bodies.len(), decoder.statics.len(), decoder.particles.len(), decoder.emitters.len(),
                        s.contacts, s.solver_passes, s.deepest_penetration, s.kinetic_energy, s.step_ms, s.overruns, bytes.len()
                    )?;
                }
                out.flush()?;
            }
            // Behind: catch up to the present from the server's state, rather than wait
            // for the next key frame.
            // (On a reduced-rate stream, for slow links, the next key frame does.)
            Err(e @ ricochet_protocol::frame::DecodeError::OutOfSync { .. }) => {
                tracing::debug!("{e}");
                if client.every() == 1 {
                    if let Ok(state) = client.state(Duration::from_secs(2)) {
                        let _ = decoder.apply(&state);
                    }
                }
            }
            Err(e) => tracing::debug!("frame skipped: {e}"),
        }
    }
}

fn record(network: &Network, world: &str, file: &Path, seconds: Option<f64>) -> Result<i32> {
    let client = Client::open(network, world)?;
    let events = client.events()?;
    let mut out = std::io::BufWriter::new(
        std::fs::File::create(file).with_context(|| format!("cannot create {}", file.display()))?,
    );
    writeln!(out, "# input log of world `{world}`: {{\"frame\": N, \"action\": ...}} per applied world command")?;
    out.flush()?;
    let began = Instant::now();
    let limit = seconds.map(Duration::from_secs_f64);
    let mut count = 0;
    while limit.is_none_or(|l| began.elapsed() < l) {
        let Some(sample) = events
            .recv_timeout(Duration::from_millis(100))
            .map_err(|e| anyhow!("{e}"))?
        else {
            continue;
        };
        let event = parse_event(&sample)?;
        if let (true, Some(Command::World(action))) = (event.ok, event.command) {
            serde_json::to_writer(
                &mut out,
                &TimedAction {
                    frame: event.frame,
                    action,
                },
            )?;
            writeln!(out)?;
            out.flush()?;
            count += 1;
        }
    }
    eprintln!("recorded {count} commands to {}", file.display());
    Ok(0)
}

fn replay(
    network: &Network,
    world: &str,
    file: &Path,
    until: Option<u64>,
    resume: bool,
    timeout: Duration,
) -> Result<i32> {
    let text =
        std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    let log = parse_input_log(&text).map_err(|e| anyhow!("{}: {e}", file.display()))?;
    let client = Client::open(network, world)?;
    let ask = |command: Command| -> Result<()> {
        let reply = client.request_retrying(&command, timeout, ATTEMPTS)?;
        if !reply.ok {
            bail!(
                "{} refused: {}",
                command.to_json(),
                reply.error.unwrap_or_default()
            );
        }
        Ok(())
    };
    ask(Command::Server(ServerCommand::Reset { paused: true }))?;
    let mut frame = 0u64;
    // Where a replay stopped, and the state it left the world in.
    let stopped = |done: usize, frame: u64| {
        format!(
            "the replay stopped after {done} of {} commands: the world was reset and is paused at about frame {frame} \
             (`ricochet send resume` runs it on; `ricochet replay` again starts over)",
            log.len()
        )
    };
    for (done, entry) in log.iter().enumerate() {
        if entry.frame > frame {
            step(&client, entry.frame - frame, timeout).with_context(|| stopped(done, frame))?;
            frame = entry.frame;
        }
        let reply = client
            .request_retrying(&Command::World(entry.action.clone()), timeout, ATTEMPTS)
            .with_context(|| stopped(done, frame))?;
        if !reply.ok {
            eprintln!(
                "frame {}: {} refused: {}",
                entry.frame,
                serde_json::to_string(&entry.action)?,
                reply.error.unwrap_or_default()
            );
        }
    }
    if let Some(end) = until {
        if end > frame {
            step(&client, end - frame, timeout).with_context(|| stopped(log.len(), frame))?;
            frame = end;
        }
    }
    if resume {
        ask(Command::Server(ServerCommand::Resume)).with_context(|| stopped(log.len(), frame))?;
    }
    eprintln!(
        "replayed {} commands; the world is at frame {frame}{}",
        log.len(),
        if resume { " and running" } else { ", paused" }
    );
    Ok(0)
}

/// Steps a paused world `n` frames, in bounded chunks so each request replies in time.
fn step(client: &Client, mut n: u64, timeout: Duration) -> Result<()> {
    while n > 0 {
        let chunk = n.min(600) as u32;
        let reply = client.request_retrying(
            &Command::Server(ServerCommand::Step { n: chunk }),
            timeout,
            ATTEMPTS,
        )?;
        if !reply.ok {
            bail!("step refused: {}", reply.error.unwrap_or_default());
        }
        n -= chunk as u64;
    }
    Ok(())
}
