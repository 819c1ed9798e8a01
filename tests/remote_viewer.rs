//! A web viewer on one machine, opened from another: `ricochet-viewer --bind 0.0.0.0`
//! prints a URL naming this machine's address (not 0.0.0.0, which no other machine can
//! open), and from a second machine both the page and the gRPC proxy it reads answer.
//! The commands are README.md's quick start ("a viewer on another machine"), read from
//! it and run as written.
//!
//! The two machines are two network namespaces made by the test, joined by a veth pair:
//! the server and the viewer run in the first, the fetches (Python's urllib) in the
//! second. Needs root and iproute2 (`.ci/install`); the namespaces are removed when the
//! test ends.

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command as Process, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use common::*;

/// The two namespaces; removed when dropped.
struct Machines {
    viewer: String,
    remote: String,
    viewer_ip: String,
}

impl Machines {
    fn make() -> Result<Machines, String> {
        let id = std::process::id() % 10_000;
        let net = 100 + id % 150;
        let machines = Machines {
            viewer: format!("rvv{id}"),
            remote: format!("rvr{id}"),
            viewer_ip: format!("10.214.{net}.1"),
        };
        for name in [&machines.viewer, &machines.remote] {
            sh(&["ip", "netns", "add", name])?;
            sh(&["ip", "-n", name, "link", "set", "lo", "up"])?;
        }
        let (here, there) = (format!("rvva{id}"), format!("rvvb{id}"));
        sh(&[
            "ip",
            "-n",
            &machines.viewer,
            "link",
            "add",
            &here,
            "type",
            "veth",
            "peer",
            "name",
            &there,
            "netns",
            &machines.remote,
        ])?;
        for (ns, dev, ip) in [
            (&machines.viewer, &here, machines.viewer_ip.clone()),
            (&machines.remote, &there, format!("10.214.{net}.2")),
        ] {
            sh(&[
                "ip",
                "-n",
                ns,
                "addr",
                "add",
                &format!("{ip}/24"),
                "dev",
                dev,
            ])?;
            sh(&["ip", "-n", ns, "link", "set", dev, "up"])?;
        }
        Ok(machines)
    }
}

impl Drop for Machines {
    fn drop(&mut self) {
        for name in [&self.viewer, &self.remote] {
            let _ = sh(&["ip", "netns", "del", name]);
        }
    }
}

/// Fetches `url` from the remote machine: the HTTP status and the body's first bytes
/// (an error status is an answer too: the server was reached).
const FETCH: &str = r#"
import sys, urllib.request, urllib.error
try:
    with urllib.request.urlopen(sys.argv[1], timeout=10) as r:
        print(r.status, r.read(4000).decode("utf-8", "replace"))
except urllib.error.HTTPError as e:
    print(e.code, "")
"#;

#[test]
fn a_web_viewer_bound_to_every_interface_opens_from_another_machine() {
    let machines = Machines::make().unwrap_or_else(|e| {
        panic!("cannot make the network namespaces (this test needs root and iproute2): {e}")
    });
    // README.md's quick start, run as written in the viewer's namespace.
    let blocks = readme_blocks("Quick start: a viewer on another machine");
    assert_eq!(blocks.len(), 1, "{blocks:?}");
    let (lang, script) = &blocks[0];
    assert_eq!(lang, "sh");
    assert!(script.contains("--bind 0.0.0.0"), "{script}");
    let mut shell = Process::new("ip");
    shell
        .args([
            "netns",
            "exec",
            &machines.viewer,
            "bash",
            "-euo",
            "pipefail",
            "-c",
        ])
        .arg(format!("ip link set lo up\n{script}"))
        .current_dir(root())
        .env("PATH", path_with_binaries())
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped());
    let mut viewer = Group::spawn(&mut shell);
    let stdout = viewer.0.stdout.take().unwrap();
    let (lines, printed) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = lines.send(line);
        }
    });
    let line = loop {
        let line = printed
            .recv_timeout(Duration::from_secs(60))
            .expect("the viewer prints the address to open");
        if line.contains("open http") {
            break line;
        }
    };
    let url = line.split_whitespace().last().unwrap().to_string();
    let ip = &machines.viewer_ip;
    assert_eq!(
        url,
        format!("http://{ip}:9090/?url=rerun%2Bhttp://{ip}:9876/proxy"),
        "the URL names the machine's address"
    );

    let fetch = |url: &str| {
        let out = Process::new("ip")
            .args([
                "netns",
                "exec",
                &machines.remote,
                "python3",
                "-c",
                FETCH,
                url,
            ])
            .output()
            .expect("python3 runs");
        assert!(
            out.status.success(),
            "{url} from the other machine: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let page = fetch(&url);
    assert!(
        page.starts_with("200 ") && page.contains("<html"),
        "the page: {page}"
    );
    let proxy = fetch(&format!("http://{ip}:9876/proxy"));
    let status: u16 = proxy[..3].parse().unwrap_or_else(|_| panic!("{proxy}"));
    assert!(
        (100..600).contains(&status),
        "the proxy answers over HTTP: {proxy}"
    );
}
