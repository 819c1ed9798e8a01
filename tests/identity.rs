//! Who a message is from, end to end with real processes on loopback: a client's request
//! ids cannot be guessed by another peer, a peer holding hundreds of a world's liveliness
//! tokens holds up no client (Rust or Python), and sender ids a session makes up share one
//! sender's rate instead of each having its own. Every wait is bounded.

mod common;

use std::process::Command as Process;
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, ServerCommand};
use ricochet_protocol::net::{Mode, Network};
use zenoh::Wait;

/// A peer that sees a client's requests (here a queryable on the world's `rpc` key: in the
/// open deployment any peer may declare one) claims the client's sender id and sends, under
/// the request ids it guesses come next, a `pause` of its own. The server applies a command
/// once per sender and id and answers a repeat with the first answer: a guessed id would
/// make the client's real `step` "answered" by the forger's `pause` and never applied. The
/// client's ids are random, so every step is applied.
#[test]
fn request_ids_cannot_be_guessed_and_pre_answered_by_another_peer() {
    let server = Server::start("impulse.toml", "preanswered", &[]);
    server.wait_up();
    // The snooper listens too, and the client connects to it and to the server.
    let snooper_endpoint = free_endpoint();
    let mut snooper_network = server.network();
    snooper_network.listen = vec![snooper_endpoint.clone()];
    let snooper = Client::open(&snooper_network, "preanswered").expect("snooper session");
    let both = Network::client(Mode::Peer, vec![server.endpoint.clone(), snooper_endpoint]);
    let client = Client::open(&both, "preanswered").expect("client session");
    let seen: Arc<std::sync::Mutex<Vec<(zenoh::session::EntityGlobalId, String)>>> = Arc::default();
    let _snoop = {
        let seen = seen.clone();
        snooper
            .session()
            .declare_queryable(snooper.keys().rpc.clone())
            .callback(move |query| {
                let id = query
                    .payload()
                    .and_then(|p| serde_json::from_slice::<serde_json::Value>(&p.to_bytes()).ok())
                    .and_then(|v| v.get("id").and_then(|i| i.as_str()).map(str::to_string));
                if let (Some(source), Some(id)) = (query.source_info(), id) {
                    seen.lock().unwrap().push((*source.source_id(), id));
                }
            })
            .wait()
            .expect("declare the snooping queryable")
    };
    // Bounded: until the snooper has seen one of the client's requests.
    let began = Instant::now();
    let (victim, last) = loop {
        assert!(request(&client, Command::Server(ServerCommand::Pause)).ok);
        if let Some(seen) = seen.lock().unwrap().last().cloned() {
            break seen;
        }
        assert!(began.elapsed() < TIMEOUT, "the snooper never saw a request");
        std::thread::sleep(Duration::from_millis(20));
    };
    // The guesses: the ids that follow the one seen, as a counter would give them.
    let digits: String = last.chars().filter(char::is_ascii_digit).collect();
    let next = if last.len() == digits.len() + 1 {
        digits.parse::<u128>().unwrap_or(0)
    } else {
        u128::from_str_radix(last.trim_start_matches('r'), 16).unwrap_or(0)
    };
    let guesses: Vec<String> = (1..=40u128)
        .flat_map(|k| {
            [
                format!("r{}", next.wrapping_add(k)),
                format!("r{:032x}", next.wrapping_add(k)),
            ]
        })
        .collect();
    for (k, guess) in guesses.iter().enumerate() {
        let forged = serde_json::json!({"do": "pause", "id": guess}).to_string();
        let replies = snooper
            .session()
            .get(snooper.keys().rpc.as_str())
            .source_info(zenoh::sample::SourceInfo::new(victim, k as u32))
            .payload(forged)
            .timeout(TIMEOUT)
            .wait()
            .expect("a forged request goes out");
        // The server's answer to the forgery (applied: it is a pause).
        while replies.recv_timeout(TIMEOUT).ok().flatten().is_some() {}
    }
    let paused_at = |client: &Client| {
        let reply = request(client, Command::Server(ServerCommand::Pause));
        assert!(reply.ok, "{reply:?}");
        reply.frame
    };
    let start = paused_at(&client);
    for _ in 0..20 {
        let reply = request(&client, Command::Server(ServerCommand::Step { n: 1 }));
        assert!(reply.ok, "{reply:?}");
    }
    // Bounded: until the world has run the steps asked for (a step runs after its reply).
    let began = Instant::now();
    let mut frame = paused_at(&client);
    while frame < start + 20 && began.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(50));
        frame = paused_at(&client);
    }
    assert_eq!(
        frame,
        start + 20,
        "20 steps asked from frame {start}: some were answered without being applied"
    );
    let id = ricochet_protocol::client::request_id();
    assert!(id.len() == 33 && id != ricochet_protocol::client::request_id());
}

/// One peer holds hundreds of the world's liveliness tokens (under made-up ids) and
/// answers nothing: a client still finds the server (the one holder that answers), its
/// requests, info and frames come within their timeouts, and its error on a world no
/// server holds names a few of the holders, not all.
#[test]
fn hundreds_of_spare_tokens_do_not_hold_up_a_client() {
    let server = Server::start("impulse.toml", "crowded", &[]);
    server.wait_up();
    // The flooder listens too, and the client connects to it and to the server.
    let flooder_endpoint = free_endpoint();
    let mut flooder_network = server.network();
    flooder_network.listen = vec![flooder_endpoint.clone()];
    let flooder = Client::open(&flooder_network, "crowded").expect("flooder session");
    let tokens: Vec<_> = (0..300)
        .map(|k| {
            flooder
                .session()
                .liveliness()
                .declare_token(flooder.keys().alive_token(&format!("{k:032x}")))
                .wait()
                .unwrap()
        })
        .collect();
    let both = Network::client(
        Mode::Peer,
        vec![server.endpoint.clone(), flooder_endpoint.clone()],
    );
    // On a thread, so that a client held up for good fails the test instead of hanging it.
    let (finished, done) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let client = Client::open(&both, "crowded").expect("client session");
        let began = Instant::now();
        while client.servers(TIMEOUT).unwrap().len() < 301 {
            assert!(began.elapsed() < TIMEOUT, "the spare tokens never showed");
            std::thread::sleep(Duration::from_millis(50));
        }
        for _ in 0..5 {
            let reply = request(&client, Command::World(Action::Deselect));
            assert!(reply.ok, "{reply:?}");
            let info = client.info(TIMEOUT).expect("the server's info");
            assert_eq!(info.scene, "impulse.toml");
        }
        let frames = client.frames().unwrap();
        let began = Instant::now();
        while frames
            .recv_timeout(Duration::from_millis(200))
            .unwrap()
            .is_none()
        {
            assert!(began.elapsed() < TIMEOUT, "no frame taken from the server");
        }
        let _ = finished.send(());
    });
    match done.recv_timeout(Duration::from_secs(60)) {
        Ok(()) => {}
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => panic!("the client failed"),
        Err(e) => panic!("the client was held up by the tokens: {e}"),
    }
    // The Python client too, within a bound.
    let python = python();
    let mut child = Process::new(&python)
        .arg(root().join("assets/scripts/ricochet_client.py"))
        .args(["--world", "crowded", "--connect", &server.endpoint])
        .args(["--connect", &flooder_endpoint, "send", "deselect"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("python3 runs");
    let began = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if began.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("the Python client was held up by the tokens");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let out = ok(&child.wait_with_output().unwrap());
    assert!(
        out.contains("\"ok\":true") || out.contains("\"ok\": true"),
        "{out}"
    );
    drop(tokens);
}

/// One session floods snapshot queries, each claiming one of 20 made-up sender ids: a claim
/// that names no session connected to the server is charged to the anonymous sender, so
/// the flood is answered at one sender's rate, not twenty's; a real client's query is
/// still answered.
#[test]
fn made_up_sender_ids_share_one_bucket() {
    let server = Server::start("emitters.toml", "claimed", &[]);
    server.wait_up();
    made_up_ids_flood_at_one_senders_rate(&server, &server.client());
}

/// The same flood through a session in router mode connected to the server: a process may
/// open one at will, so it does not make the server take claims as they are (before, 20
/// made-up ids were answered at 20 times one sender's rate through it).
#[test]
fn made_up_sender_ids_through_a_router_mode_session_share_one_bucket() {
    let server = Server::start("emitters.toml", "routed", &[]);
    server.wait_up();
    let router = Client::open(
        &Network::client(Mode::Router, vec![server.endpoint.clone()]),
        "routed",
    )
    .expect("a router-mode session");
    wait_answered(&router, "the world through a router-mode session");
    made_up_ids_flood_at_one_senders_rate(&server, &router);
}

/// `flooder` sends 600 snapshot queries under 20 made-up ids: at most one sender's rate is
/// answered, and a connected client is still answered after.
fn made_up_ids_flood_at_one_senders_rate(server: &Server, flooder: &Client) {
    let key = flooder.keys().snapshot.clone();
    // Ids of sessions that exist but are connected to nothing: a made-up claim.
    let (made_up, _isolated): (Vec<_>, Vec<_>) = (0..20)
        .map(|_| {
            let mut config = zenoh::Config::default();
            config
                .insert_json5("scouting/multicast/enabled", "false")
                .unwrap();
            config.insert_json5("listen/endpoints", "[]").unwrap();
            let session = zenoh::open(config).wait().expect("an isolated session");
            let id = session
                .declare_publisher("elsewhere")
                .wait()
                .expect("a publisher")
                .id();
            (id, session)
        })
        .unzip();
    let (answered, sent_in) = flood_queries(flooder, &key, 600, |k| {
        Some(zenoh::sample::SourceInfo::new(made_up[k as usize % 20], k))
    });
    // One sender's bucket: 100 at once, 50 a second.
    let allowed = 100.0 + 50.0 * sent_in;
    eprintln!("{answered} of 600 queries under 20 made-up ids answered in {sent_in:.2} s");
    assert!(
        (answered as f64) <= allowed + 10.0,
        "{answered} of 600 queries answered in {sent_in:.2} s: the made-up ids had buckets of their own (one allows {allowed:.0})"
    );
    let other = server.client();
    let snapshot = other
        .snapshot(Duration::from_secs(10))
        .expect("a connected client's query is answered");
    assert!(!snapshot.is_empty());
}

/// A spy that sees a client's commands borrows its id, three ways at once: bare claims of
/// the id, the client's own signed messages sent again, and those with a new counter (a
/// signature that no longer holds). With signed ids (the default) the client's requests
/// are all answered while the spy floods; with `--sender-ids connected` (the defence off)
/// the flood spends the client's rate and its requests are refused.
#[test]
fn a_connected_clients_id_cannot_be_borrowed() {
    let defended = borrowed_id_refusals(&[]);
    let undefended = borrowed_id_refusals(&["--sender-ids", "connected"]);
    eprintln!("requests refused while a spy borrowed the id: {defended} of 20 signed, {undefended} of 20 without the defence");
    assert_eq!(defended, 0, "the spy spent the client's rate");
    assert!(
        undefended >= 5,
        "without the defence the spy should spend the client's rate: {undefended} of 20 refused"
    );
}

/// Of 20 requests from a client, how many are refused for its rate while a spy floods under
/// its id (rate 20 a second, 20 at once).
fn borrowed_id_refusals(extra: &[&str]) -> usize {
    let world = "borrowed";
    let mut args = vec!["--sender-rate", "20", "--sender-burst", "20"];
    args.extend_from_slice(extra);
    let server = Server::start("impulse.toml", world, &args);
    server.wait_up();
    // The spy listens, and the client connects to it as well as to the server: the spy
    // sees the client's commands as any peer on its path could.
    let spy_endpoint = free_endpoint();
    let mut spy_network = server.network();
    spy_network.listen = vec![spy_endpoint.clone()];
    let spy = Client::open(&spy_network, world).expect("spy session");
    let both = Network::client(Mode::Peer, vec![server.endpoint.clone(), spy_endpoint]);
    let client = Client::open(&both, world).expect("client session");
    type Seen = (zenoh::session::EntityGlobalId, Vec<u8>, Vec<u8>);
    let seen: Arc<std::sync::Mutex<Vec<Seen>>> = Arc::default();
    let _watch = {
        let seen = seen.clone();
        spy.session()
            .declare_subscriber(spy.keys().cmd.clone())
            .callback(move |sample| {
                if let (Some(source), Some(attachment)) =
                    (sample.source_info(), sample.attachment())
                {
                    seen.lock().unwrap().push((
                        *source.source_id(),
                        sample.payload().to_bytes().into_owned(),
                        attachment.to_bytes().into_owned(),
                    ));
                }
            })
            .wait()
            .expect("the spy's subscriber")
    };
    // Bounded: until the spy has seen a few of the client's (refused, harmless) commands.
    let began = Instant::now();
    while seen.lock().unwrap().len() < 3 {
        client.send_raw(b"{}".to_vec()).expect("a command goes out");
        assert!(began.elapsed() < TIMEOUT, "the spy never saw a command");
        std::thread::sleep(Duration::from_millis(100));
    }
    let captured = seen.lock().unwrap().clone();
    let victim = captured[0].0;
    let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flood = {
        let done = done.clone();
        let key = spy.keys().cmd.clone();
        std::thread::spawn(move || {
            let publisher = spy.session().declare_publisher(key).wait().unwrap();
            let began = Instant::now();
            let mut k = 0u32;
            // Bounded: until the client is done, 20 s at most.
            while !done.load(std::sync::atomic::Ordering::Relaxed)
                && began.elapsed() < Duration::from_secs(20)
            {
                for (_, payload, attachment) in &captured {
                    k += 1;
                    let source = || zenoh::sample::SourceInfo::new(victim, k);
                    publisher
                        .put(b"{}".to_vec())
                        .source_info(source())
                        .wait()
                        .unwrap();
                    publisher
                        .put(payload.clone())
                        .source_info(source())
                        .attachment(attachment.clone())
                        .wait()
                        .unwrap();
                    let mut moved = attachment.clone();
                    moved[33] = moved[33].wrapping_add(100);
                    publisher
                        .put(payload.clone())
                        .source_info(source())
                        .attachment(moved)
                        .wait()
                        .unwrap();
                }
                std::thread::sleep(Duration::from_micros(200));
            }
            k
        })
    };
    std::thread::sleep(Duration::from_millis(300));
    let mut refused = 0;
    for _ in 0..20 {
        let reply = request(&client, Command::Server(ServerCommand::Resume));
        if !reply.ok {
            assert!(
                reply.error.as_deref().unwrap_or("").contains("rate limit"),
                "{reply:?}"
            );
            refused += 1;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    let sent = flood.join().expect("the flood ends");
    eprintln!("the spy sent {} messages under the client's id", sent * 3);
    refused
}

/// The Python client signs its requests as the Rust one does: while an unsigned session
/// floods (spending the anonymous sender's rate), its requests are answered under a rate of
/// its own. With its signing turned off in the script, they share the flooded rate and are
/// refused, which shows the test can tell.
#[test]
fn the_python_clients_requests_are_signed_and_keep_their_own_rate() {
    let server = Server::start(
        "impulse.toml",
        "pysigned",
        &["--sender-rate", "5", "--sender-burst", "10"],
    );
    server.wait_up();
    let flooder = Client::with_session(server.network().open().expect("a session"), "pysigned")
        .expect("an unsigned client");
    let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flood = {
        let done = done.clone();
        std::thread::spawn(move || {
            let began = Instant::now();
            // Bounded: until the Python runs are done, 60 s at most.
            while !done.load(std::sync::atomic::Ordering::Relaxed)
                && began.elapsed() < Duration::from_secs(60)
            {
                flooder.send_raw(b"{}".to_vec()).unwrap();
                std::thread::sleep(Duration::from_millis(2));
            }
        })
    };
    std::thread::sleep(Duration::from_millis(300));
    let run = |signed: bool| -> (usize, usize) {
        let unsign = if signed {
            ""
        } else {
            "ricochet.session.ids.of_session = lambda zid: None\n"
        };
        let script = format!(
            "import ricochet, ricochet.session\n{unsign}\
             w = ricochet.World.connect({endpoint:?}, world='pysigned', attempts=1)\n\
             replies = [w.send_raw({{'do': 'resume'}}) for _ in range(8)]\n\
             print(sum(r.ok for r in replies), sum('rate limit' in (r.error or '') for r in replies))\n",
            endpoint = server.endpoint
        );
        let out = ok(&Process::new(python())
            .args(["-c", &script])
            .output()
            .expect("python runs"));
        let counts: Vec<usize> = out.split_whitespace().map(|n| n.parse().unwrap()).collect();
        (counts[0], counts[1])
    };
    let (signed_ok, _) = run(true);
    let (unsigned_ok, unsigned_limited) = run(false);
    done.store(true, std::sync::atomic::Ordering::Relaxed);
    flood.join().unwrap();
    eprintln!("while an unsigned session floods: {signed_ok} of 8 signed requests answered, {unsigned_ok} of 8 unsigned ({unsigned_limited} refused for the rate)");
    assert_eq!(
        signed_ok, 8,
        "the Python client's signed requests kept their own rate"
    );
    assert!(
        unsigned_limited >= 4,
        "unsigned, the Python client shares the flooded rate: {unsigned_ok} of 8 answered"
    );
}
