//! Floods, slow peers, long work and retries against a real server on loopback: requests
//! are answered while a flood runs, a retried request is answered and not applied again,
//! long `step` work is sliced so others are served meanwhile, and a subscriber that stops
//! reading holds nothing up. Every wait is bounded; no test times the server.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use ricochet_protocol::client::Client;
use ricochet_protocol::command::{Action, Command, Health, Reply, ServerCommand};
use zenoh::Wait;

fn health(client: &Client) -> Health {
    client
        .info(TIMEOUT)
        .expect("the world's info")
        .health
        .expect("the server reports its health")
}

fn raw(client: &Client, json: &str) -> Reply {
    client
        .request_raw(json.as_bytes().to_vec(), TIMEOUT)
        .expect("a reply")
}

#[test]
fn a_retried_request_is_answered_again_not_applied_twice() {
    let server = Server::start("impulse.toml", "retry", &["--paused"]);
    let client = server.client();
    let before = health(&client);
    let spawn = r#"{"do":"spawn_minion","at":[100,60],"id":"spawn-1"}"#;
    let first = raw(&client, spawn);
    assert!(first.ok && first.ids.len() == 1, "{first:?}");
    assert_eq!(first.id.as_deref(), Some("spawn-1"));
    let again = raw(&client, spawn);
    assert_eq!(again, first, "the retry got the first answer");
    // Another id is another command: a second minion.
    let other = raw(
        &client,
        r#"{"do":"spawn_minion","at":[100,60],"id":"spawn-2"}"#,
    );
    assert!(other.ok && other.ids != first.ids, "{other:?}");
    // The same id from another sender is that sender's own.
    let stranger = raw(&server.client(), spawn);
    assert!(stranger.ok && stranger.ids != first.ids, "{stranger:?}");
    let h = health(&client);
    assert_eq!(h.retries - before.retries, 1, "{h:?}");
    assert_eq!(h.applied - before.applied, 3, "{h:?}");
    // A bad id is refused, naming it.
    let bad = raw(&client, r#"{"do":"deselect","id":7}"#);
    assert!(
        !bad.ok && bad.error.as_deref().unwrap().contains("`id`"),
        "{bad:?}"
    );
}

#[test]
fn dropped_fire_and_forget_commands_are_summed_up_in_an_event_not_echoed() {
    let server = Server::start("impulse.toml", "unanswered", &[]);
    let client = server.client();
    let events = client.events().unwrap();
    // Commands sent without a reply key, each over the size limit: nobody can be answered.
    let sent = 40;
    let oversized = vec![b' '; 70_000];
    // Sent blocking, not dropped by zenoh when its queue is full (a put's default): on a
    // loaded machine all but one of 40 were once dropped on the way, and one drop cannot
    // show drops summed up.
    for _ in 0..sent {
        client
            .session()
            .put(&client.keys().cmd, oversized.clone())
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .wait()
            .unwrap();
    }
    // The drops come back summed up, at most an event a second however many were sent:
    // the sums add up to what the server counted refused (zenoh itself may drop a put on
    // the way; what the server saw is what it sums).
    let began = Instant::now();
    let (mut summaries, mut dropped) = (0u64, 0u64);
    // The server's count, and since when it has stood still: the puts may still be
    // arriving when the first sum goes out.
    let (mut counted, mut still_since) = (0u64, Instant::now());
    loop {
        if let Ok(Some(sample)) = events.recv_timeout(Duration::from_millis(100)) {
            let event: ricochet_protocol::command::Event =
                serde_json::from_slice(&sample.payload().to_bytes()).unwrap();
            if let Some(error) = event.error.filter(|e| e.starts_with("dropped ")) {
                assert!(!event.ok && event.command.is_none(), "{error}");
                assert!(error.contains("over the size limit"), "{error}");
                summaries += 1;
                dropped += error["dropped ".len()..]
                    .split(' ')
                    .next()
                    .and_then(|n| n.parse::<u64>().ok())
                    .expect("a count");
            }
        }
        let refused = health(&client).refused;
        if refused != counted {
            (counted, still_since) = (refused, Instant::now());
        }
        // Sums go out at most once a second: a count that stood still for 1.5 s is whole.
        if refused > 0 && dropped == refused && still_since.elapsed() > Duration::from_millis(1500)
        {
            break;
        }
        assert!(
            began.elapsed() < TIMEOUT,
            "{dropped} drops summed up in {summaries} events, {refused} refused"
        );
    }
    let seconds = began.elapsed().as_secs_f64().ceil() as u64;
    assert!(
        summaries <= seconds + 1,
        "{summaries} events in {seconds} s"
    );
    assert!(
        dropped > summaries,
        "{dropped} drops in {summaries} events: one each?"
    );
}

#[test]
fn a_flood_of_commands_starves_neither_requests_nor_the_clock() {
    let server = Server::start("impulse.toml", "flood", &[]);
    let flooder = Arc::new(server.client());
    let client = server.client();
    let frames_before = health(&client).frames;
    let flooding = Arc::new(AtomicBool::new(true));
    let flood = {
        let (flooder, flooding) = (flooder.clone(), flooding.clone());
        std::thread::spawn(move || {
            let mut sent = 0u64;
            let began = Instant::now();
            // Bounded: at most 60 000 commands or 20 s.
            while flooding.load(Ordering::Relaxed)
                && sent < 60_000
                && began.elapsed() < Duration::from_secs(20)
            {
                // One in three unknown, the rest valid.
                let command = match sent % 3 {
                    0 => br#"{"do":"no_such_command"}"#.to_vec(),
                    _ => br#"{"do":"deselect"}"#.to_vec(),
                };
                flooder.send_raw(command).unwrap();
                sent += 1;
            }
            sent
        })
    };
    // Every request of another client is answered while the flood runs.
    for _ in 0..20 {
        let reply = request(&client, Command::World(Action::Deselect));
        assert!(reply.ok, "{reply:?}");
    }
    // The flooder's own request is answered too: refused for its rate, or applied.
    let answered = flooder
        .request(&Command::World(Action::Deselect), TIMEOUT)
        .expect("the flooder's request is answered");
    flooding.store(false, Ordering::Relaxed);
    let sent = flood.join().unwrap();
    let h = health(&client);
    assert!(
        h.rate_limited > 0,
        "{sent} commands in a burst went over the sender's rate: {h:?} ({answered:?})"
    );
    assert!(h.refused > 0, "the unknown commands were refused: {h:?}");
    // The clock kept stepping through it.
    let began = Instant::now();
    while health(&client).frames <= frames_before + 30 {
        assert!(began.elapsed() < TIMEOUT, "the world stopped stepping");
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn long_steps_run_in_slices_and_others_are_served_meanwhile() {
    let server = Server::start("pyramid-10.toml", "slices", &["--paused"]);
    let client = server.client();
    let other = server.client();
    let start = health(&client).frames;
    // A step request is answered once its steps have run.
    let reply = request(&client, Command::Server(ServerCommand::Step { n: 500 }));
    assert!(reply.ok, "{reply:?}");
    assert!(
        health(&client).frames >= start + 500,
        "answered before its steps ran"
    );
    // 30 000 steps asked for at once; a request of another client is answered before
    // they are all done.
    for _ in 0..3 {
        client
            .send(&Command::Server(ServerCommand::Step { n: 10_000 }))
            .unwrap();
    }
    let began = Instant::now();
    let mut served_midway = false;
    loop {
        let reply = request(&other, Command::World(Action::Deselect));
        assert!(reply.ok, "{reply:?}");
        let target = start + 500 + 30_000;
        if reply.frame > start + 500 && reply.frame < target {
            served_midway = true;
        }
        if reply.frame >= target {
            break;
        }
        assert!(began.elapsed() < TIMEOUT * 6, "the steps never finished");
    }
    assert!(served_midway, "no request was served while the steps ran");
    // Too many steps waiting are refused, with the reason.
    for _ in 0..10 {
        client
            .send(&Command::Server(ServerCommand::Step { n: 10_000 }))
            .unwrap();
    }
    // The same client: its commands are taken in the order it sent them.
    let refused = request(&client, Command::Server(ServerCommand::Step { n: 10_000 }));
    assert!(
        !refused.ok && refused.error.as_deref().unwrap().contains("still to run"),
        "{refused:?}"
    );
}

#[test]
fn a_subscriber_that_stops_reading_holds_nothing_up() {
    let server = Server::start(
        "particles-10k.toml",
        "stalled",
        &["--paused", "--keyframe-interval", "1"],
    );
    let client = server.client();
    // A peer whose frame subscriber never returns: its session stops reading, its
    // socket fills, and the server's queue to it with it.
    let stalled = server.client();
    let release = Arc::new(AtomicBool::new(false));
    let hold = release.clone();
    let _stuck = stalled
        .session()
        .declare_subscriber(&stalled.keys().frame)
        .callback(move |_| {
            let began = Instant::now();
            while !hold.load(Ordering::Relaxed) && began.elapsed() < Duration::from_secs(60) {
                std::thread::sleep(Duration::from_millis(10));
            }
        })
        .wait()
        .unwrap();
    let start = health(&client).frames;
    for _ in 0..4 {
        let reply = request(&client, Command::Server(ServerCommand::Step { n: 1000 }));
        assert!(reply.ok, "{reply:?}");
    }
    assert!(health(&client).frames >= start + 4000);
    // Real time goes on too.
    resume(&client);
    let resumed = health(&client).frames;
    let began = Instant::now();
    while health(&client).frames < resumed + 60 {
        assert!(began.elapsed() < TIMEOUT, "the clock stalled");
        std::thread::sleep(Duration::from_millis(50));
    }
    release.store(true, Ordering::Relaxed);
}
