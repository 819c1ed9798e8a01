//! Helpers shared by the end-to-end tests: binaries, scenes, free ports, a server process
//! that is killed when dropped. Every wait is bounded.
#![allow(dead_code)]

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command as Process, Output, Stdio};
use std::time::{Duration, Instant};

pub mod python;
#[allow(unused_imports)]
pub use python::python;

use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, ServerCommand};
use ricochet_protocol::net::{Mode, Network};

pub const TIMEOUT: Duration = Duration::from_secs(10);

pub fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test binary path");
    exe.parent()
        .and_then(Path::parent)
        .expect("target/<profile>/deps")
        .to_path_buf()
}

pub fn bin(name: &str) -> PathBuf {
    let p = target_dir().join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        p.exists(),
        "{} is missing: run the tests with `cargo test --release --workspace`",
        p.display()
    );
    p
}

/// The repository's root: the tests of the root package and of the lab share these
/// helpers, so it is found from the package, not assumed to be it.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|dir| dir.join("assets/scenes").is_dir())
        .expect("the repository's assets/scenes")
        .to_path_buf()
}

pub fn scene(name: &str) -> String {
    root()
        .join("assets/scenes")
        .join(name)
        .display()
        .to_string()
}

/// A fresh directory, removed with everything in it when dropped.
pub fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary directory")
}

pub fn free_endpoint() -> String {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("tcp/127.0.0.1:{port}")
}

/// A child process killed when dropped.
pub struct Running(pub Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A server hosting `world` from `scene_name`, listening on a fresh endpoint.
pub struct Server {
    pub endpoint: String,
    pub world: String,
    _process: Running,
}

impl Server {
    pub fn start(scene_name: &str, world: &str, extra: &[&str]) -> Server {
        let scene = scene(scene_name);
        let mut args = vec!["--scene", scene.as_str()];
        args.extend_from_slice(extra);
        Server::launch(world, &args)
    }

    /// `ricochet-server run --world WORLD --listen ENDPOINT ARGS`, once it answers.
    pub fn launch(world: &str, args: &[&str]) -> Server {
        Server::launch_at(&free_endpoint(), world, args)
    }

    /// [`Server::launch`] on `endpoint` (where a killed server listened, say).
    pub fn launch_at(endpoint: &str, world: &str, args: &[&str]) -> Server {
        let endpoint = endpoint.to_string();
        let child = Process::new(bin("ricochet-server"))
            .args(["run", "--world", world, "--listen", &endpoint])
            .args(args)
            // RICOCHET_SERVER_LOG=ricochet_server=trace shows what a test's server does.
            .env(
                "RUST_LOG",
                std::env::var("RICOCHET_SERVER_LOG").unwrap_or_else(|_| "warn".into()),
            )
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("ricochet-server starts");
        let server = Server {
            endpoint,
            world: world.to_string(),
            _process: Running(child),
        };
        server.wait_up();
        server
    }

    /// Kills the server at once (SIGKILL): no chance to flush or say goodbye.
    pub fn kill(mut self) {
        self._process.0.kill().expect("kill the server");
        self._process.0.wait().expect("the killed server is reaped");
    }

    pub fn network(&self) -> Network {
        Network::client(Mode::Peer, vec![self.endpoint.clone()])
    }

    pub fn client(&self) -> Client {
        Client::open(&self.network(), &self.world).expect("client session")
    }

    /// Waits until the server answers a request (bounded).
    pub fn wait_up(&self) {
        wait_answered(
            &self.client(),
            &format!("world {} on {}", self.world, self.endpoint),
        );
    }

    /// Runs the `ricochet` client against this server.
    pub fn cli(&self, args: &[&str]) -> Output {
        Process::new(bin("ricochet"))
            .args(["--world", &self.world, "--connect", &self.endpoint])
            .args(args)
            .env("RUST_LOG", "warn")
            .output()
            .expect("ricochet starts")
    }
}

/// Waits (bounded) until `client`'s requests are answered; `what` names the server in the
/// panic if they never are.
pub fn wait_answered(client: &Client, what: &str) {
    let began = Instant::now();
    while began.elapsed() < TIMEOUT * 3 {
        // `deselect` changes nothing but answers.
        if client
            .request(
                &Command::World(Action::Deselect),
                Duration::from_millis(500),
            )
            .is_ok()
        {
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("the server of {what} never answered");
}

pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

pub fn request(client: &Client, command: Command) -> ricochet_protocol::command::Reply {
    client.request(&command, TIMEOUT).expect("a reply")
}

pub fn resume(client: &Client) {
    assert!(request(client, Command::Server(ServerCommand::Resume)).ok);
}

/// A queryable on `key` (an impostor's) that answers every query with `reply` and counts
/// the queries it got.
pub fn answer_every_query(
    session: &zenoh::Session,
    key: &str,
    reply: &[u8],
    asked: std::sync::Arc<std::sync::atomic::AtomicUsize>,
) -> zenoh::query::Queryable<()> {
    use zenoh::Wait;
    let reply = reply.to_vec();
    session
        .declare_queryable(key.to_string())
        .callback(move |query| {
            asked.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let _ = query.reply(query.key_expr().clone(), reply.clone()).wait();
        })
        .wait()
        .expect("declare a queryable")
}
/// Runs a command (`ip`, `tc`, `nft`: the network tests' set-up); its error says which
/// and why.
pub fn sh(args: &[&str]) -> Result<(), String> {
    let out = Process::new(args[0])
        .args(&args[1..])
        .output()
        .map_err(|e| format!("{}: {e}", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// Sends `n` queries on `key` at once from `client`'s session, query `k` with the source
/// `source(k)` claims (none: the session's own), and waits for them all: how many were
/// answered with a payload (a dropped query ends with no reply), and the seconds sending
/// took.
pub fn flood_queries(
    client: &Client,
    key: &str,
    n: u32,
    source: impl Fn(u32) -> Option<zenoh::sample::SourceInfo>,
) -> (usize, f64) {
    use zenoh::Wait;
    let began = Instant::now();
    let pending: Vec<_> = (0..n)
        .map(|k| {
            let get = client.session().get(key).timeout(Duration::from_secs(20));
            match source(k) {
                Some(info) => get.source_info(info).wait(),
                None => get.wait(),
            }
            .expect("a query goes out")
        })
        .collect();
    let sent_in = began.elapsed().as_secs_f64();
    let mut answered = 0;
    for replies in pending {
        while let Ok(reply) = replies.recv() {
            if reply.result().is_ok_and(|s| !s.payload().is_empty()) {
                answered += 1;
            }
        }
    }
    (answered, sent_in)
}

/// The fenced code blocks of README.md's section `heading` (its `### ...` line), as
/// (language, text), in order: what the quick-start tests run as written.
pub fn readme_blocks(heading: &str) -> Vec<(String, String)> {
    let readme = std::fs::read_to_string(root().join("README.md")).expect("README.md");
    let start = readme
        .lines()
        .position(|l| l.trim_start_matches('#').trim() == heading && l.starts_with('#'))
        .unwrap_or_else(|| panic!("README.md has no section `{heading}`"));
    let mut blocks = Vec::new();
    let mut open: Option<(String, String)> = None;
    for line in readme.lines().skip(start + 1) {
        match &mut open {
            None if line.starts_with('#') => break,
            None => {
                if let Some(lang) = line.strip_prefix("```") {
                    open = Some((lang.trim().to_string(), String::new()));
                }
            }
            Some(_) if line.starts_with("```") => blocks.push(open.take().unwrap()),
            Some((_, text)) => {
                text.push_str(line);
                text.push('\n');
            }
        }
    }
    blocks
}

/// A process group (a shell and everything it started), killed whole when dropped.
pub struct Group(pub Child);

impl Group {
    /// Spawns `command` as the leader of a new process group.
    pub fn spawn(command: &mut Process) -> Group {
        use std::os::unix::process::CommandExt;
        Group(
            command
                .process_group(0)
                .spawn()
                .expect("the process starts"),
        )
    }
}

impl Drop for Group {
    fn drop(&mut self) {
        let _ = sh(&["kill", "-KILL", "--", &format!("-{}", self.0.id())]);
        let _ = self.0.wait();
    }
}

/// `PATH` with the built binaries first, as the README's `export PATH=...` has it.
pub fn path_with_binaries() -> std::ffi::OsString {
    let mut dirs = vec![target_dir()];
    dirs.extend(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    ));
    std::env::join_paths(dirs).expect("PATH")
}
