//! The journal's tests: resumes of journals cut short, torn, changed, of older versions,
//! and the answers a resume remembers.

use std::fs::OpenOptions;
use std::io::Write as _;

use ricochet_engine::world::Limits;

use super::super::answered::REMEMBER_FOR;
use super::*;

fn options() -> HostOptions {
    HostOptions::for_tests("journaled")
}

/// A journal of `steps` stepped frames of the shipped bounce scene, and the world's
/// frame at its end.
fn journal_of(path: &Path, steps: usize) -> u64 {
    let opts = options();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/bounce.toml");
    let text = std::fs::read_to_string(scene).unwrap();
    let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
    let mut journal = Journal::create(path, "journaled", &host, &opts).unwrap();
    for _ in 0..steps {
        host.step();
        journal.stepped(host.world.frame(), 0.0);
    }
    host.world.frame()
}

fn append(path: &Path, bytes: &[u8]) {
    let mut file = OpenOptions::new().append(true).open(path).unwrap();
    file.write_all(bytes).unwrap();
}

#[test]
fn a_last_line_cut_short_is_not_replayed_and_is_cut_off() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let frame = journal_of(&path, 5);
    let whole = std::fs::metadata(&path).unwrap().len();
    // The kill cut the next step's line short: even a line that parses is not whole
    // without its newline (it was never flushed whole, so never answered).
    append(&path, format!("{{\"at\":{}}}", frame + 1).as_bytes());
    let resumed = resume(&path, &options()).unwrap();
    assert_eq!(resumed.host.world.frame(), frame);
    assert_eq!(std::fs::metadata(&path).unwrap().len(), whole);
    // Resumed once more, the journal is whole: the same frame again.
    drop(resumed);
    assert_eq!(resume(&path, &options()).unwrap().host.world.frame(), frame);
}

/// The refusal of a journal that must not resume.
fn refusal(path: &Path, opts: &HostOptions) -> String {
    match resume(path, opts) {
        Ok(_) => panic!("{} resumed", path.display()),
        Err(e) => format!("{e:#}"),
    }
}

#[test]
fn a_last_line_torn_inside_a_character_is_torn_like_any_other() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let frame = journal_of(&path, 5);
    // The first byte of a two-byte character, then the kill.
    append(&path, b"{\"at\":\"\xc3");
    assert_eq!(resume(&path, &options()).unwrap().host.world.frame(), frame);
    // A last line that is not text is torn too (a full disk may leave any bytes) ...
    let whole = std::fs::metadata(&path).unwrap().len();
    append(&path, b"\xff\xfe\n");
    assert_eq!(resume(&path, &options()).unwrap().host.world.frame(), frame);
    assert_eq!(std::fs::metadata(&path).unwrap().len(), whole, "cut off");
    // ... but with a line after it, it is damage: refused, naming its line.
    append(&path, b"\xff\xfe\n");
    append(
        &path,
        (signed(&format!("{{\"at\":{}}}", frame + 1)) + "\n").as_bytes(),
    );
    let e = refusal(&path, &options());
    assert!(e.contains("line 7") && e.contains("not UTF-8"), "{e}");
}

#[test]
fn a_last_line_whose_checksum_does_not_match_is_dropped_and_cut_off_but_refused_in_the_middle() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let frame = journal_of(&path, 5);
    let whole = std::fs::metadata(&path).unwrap().len();
    // What a full disk can leave: a line whole up to its newline but for its checksum.
    let next = signed(&format!("{{\"at\":{}}}", frame + 1));
    let torn = next.replace('\t', "\t0");
    append(
        &path,
        (torn[..torn.len() - 1].to_string() + "\n").as_bytes(),
    );
    let resumed = resume(&path, &options()).unwrap();
    assert_eq!(resumed.host.world.frame(), frame);
    assert_eq!(std::fs::metadata(&path).unwrap().len(), whole, "cut off");
    drop(resumed);
    // The same line with a whole line after it: damage in the middle, refused.
    append(
        &path,
        (torn[..torn.len() - 1].to_string() + "\n").as_bytes(),
    );
    append(&path, (next + "\n").as_bytes());
    let e = refusal(&path, &options());
    assert!(e.contains("line 7") && e.contains("checksum"), "{e}");
}

#[test]
fn a_journals_limits_never_raise_the_servers_own() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    journal_of(&path, 2);
    let text = std::fs::read_to_string(&path).unwrap();
    // The operator resumes under --limit bodies=60: a journal written under the
    // default (100 000 bodies) would raise it, and is refused with what to do.
    let strict = HostOptions {
        limits: Limits::default().with(&["bodies=60".into()]).unwrap(),
        ..options()
    };
    let e = refusal(&path, &strict);
    assert!(
        e.contains("bodies") && e.contains("--limit bodies=100000"),
        "{e}"
    );
    // A header whose work limit is not a number is refused, not read as no limit (even
    // with its checksum made again, as an operator's edit would).
    let nan = text.replacen("step_work = 100000000.0", "step_work = nan", 1);
    assert_ne!(nan, text, "the header spells step_work as expected");
    std::fs::write(&path, resigned(&nan)).unwrap();
    let e = refusal(&path, &options());
    assert!(e.contains("step_work"), "{e}");
}

/// Every line of `text` with its checksum made again.
fn resigned(text: &str) -> String {
    text.lines()
        .map(|l| signed(l.rsplit_once('\t').map_or(l, |(t, _)| t)) + "\n")
        .collect()
}

#[test]
fn a_line_changed_after_it_was_written_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    journal_of(&path, 4);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.lines().all(|l| unsigned(l).is_some()), "{text}");
    // One digit of a stepped frame changed: another world, were it replayed.
    let changed = text.replacen("{\"at\":3}", "{\"at\":5}", 1);
    assert_ne!(changed, text);
    std::fs::write(&path, &changed).unwrap();
    let e = refusal(&path, &options());
    assert!(e.contains("line 4") && e.contains("checksum"), "{e}");
    // The header too.
    let header = text.replacen("\"journaled\"", "\"journalex\"", 1);
    std::fs::write(&path, &header).unwrap();
    let e = refusal(&path, &options());
    assert!(e.contains("line 1") && e.contains("checksum"), "{e}");
}

#[test]
fn a_journal_of_version_2_with_commands_written_after_they_ran_still_resumes() {
    use ricochet_protocol::command::Action;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let frame = journal_of(&path, 3);
    // Version 2: the command with its reply, once it ran, then more steps.
    let press = Command::World(Action::Set {
        name: "gravity".into(),
        value: serde_json::json!([0, -9]),
    });
    let opts = options();
    let text = std::fs::read_to_string(&path).unwrap();
    let header = text.lines().next().unwrap().rsplit_once('\t').unwrap().0;
    let header = header.replacen(&format!("\"journal\":{VERSION}"), "\"journal\":2", 1);
    let mut lines = vec![signed(&header)];
    lines.extend(text.lines().skip(1).map(str::to_string));
    let reply = Reply {
        ok: true,
        frame,
        id: Some("p".into()),
        ..Reply::default()
    };
    let line = Line::Command {
        frame,
        command: press.clone(),
        reply,
        sender: Some("peer".into()),
        id: Some("p".into()),
    };
    lines.push(signed(&serde_json::to_string(&line).unwrap()));
    lines.push(signed(&format!("{{\"at\":{}}}", frame + 1)));
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let resumed = resume(&path, &opts).unwrap();
    assert_eq!(resumed.host.world.frame(), frame + 1);
    assert_eq!(
        resumed.host.world.config.gravity.y, -9.0,
        "the command was replayed"
    );
    assert!(resumed.answered.get(&Some("peer".into()), "p").is_some());
}

#[test]
fn a_journal_of_version_1_without_checksums_still_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let frame = journal_of(&path, 4);
    let text = std::fs::read_to_string(&path).unwrap();
    let v1: String = text
        .lines()
        .map(|l| l.rsplit_once('\t').unwrap().0.to_string() + "\n")
        .collect::<String>()
        .replacen(&format!("\"journal\":{VERSION}"), "\"journal\":1", 1);
    assert!(!v1.contains('\t') && v1.contains("\"journal\":1"), "{v1}");
    std::fs::write(&path, &v1).unwrap();
    let mut resumed = resume(&path, &options()).unwrap();
    assert_eq!(resumed.host.world.frame(), frame);
    // The resumed server appends lines with checksums; the mixed journal resumes.
    resumed.host.step();
    resumed.journal.stepped(resumed.host.world.frame(), 0.0);
    drop(resumed);
    assert_eq!(
        resume(&path, &options()).unwrap().host.world.frame(),
        frame + 1
    );
}

#[test]
fn a_resumed_server_still_says_why_its_setting_was_picked() {
    let dir = tempfile::tempdir().unwrap();
    let (picked, plain) = (dir.path().join("picked.journal"), dir.path().join("plain"));
    let opts = options();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/bounce.toml");
    let text = std::fs::read_to_string(scene).unwrap();
    let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
    host.accuracy = Some("picked impulses 8 it for a target of 0.01".into());
    Journal::create(&picked, "journaled", &host, &opts).unwrap();
    let resumed = resume(&picked, &options()).unwrap();
    assert_eq!(resumed.host.info().accuracy, host.accuracy);
    // A journal of a server without a target says none (and has no such field).
    journal_of(&plain, 1);
    assert!(!std::fs::read_to_string(&plain)
        .unwrap()
        .contains("accuracy"));
    assert_eq!(
        resume(&plain, &options()).unwrap().host.info().accuracy,
        None
    );
}

#[test]
fn a_bad_line_in_the_middle_is_refused_naming_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let frame = journal_of(&path, 3);
    append(&path, b"{\"at\":garbage}\n");
    append(&path, format!("{{\"at\":{}}}\n", frame + 1).as_bytes());
    let error = refusal(&path, &options());
    // The header, three steps, then the bad line: line 5.
    assert!(error.contains("world.journal line 5"), "{error}");
}

#[test]
fn an_empty_journal_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    std::fs::write(&path, "").unwrap();
    let error = refusal(&path, &options());
    assert!(error.contains("line 1: empty"), "{error}");
}

#[test]
fn a_resume_remembers_the_ids_of_its_last_seconds_as_old_as_they_were() {
    use ricochet_protocol::command::{Action, Direction, ServerCommand};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("world.journal");
    let opts = options();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../assets/scenes/bounce.toml");
    let text = std::fs::read_to_string(scene).unwrap();
    let mut host = Hosted::load(text, PathBuf::from(scene), &opts).unwrap();
    let mut journal = Journal::create(&path, "journaled", &host, &opts).unwrap();
    let window = (REMEMBER_FOR.as_secs_f64() / host.world.config.dt).ceil() as u64;
    let sender: Sender = Some("peer".into());
    let press = Command::World(Action::Press {
        dir: Direction::Left,
    });
    let end = window + 300;
    let mut step_due = 0;
    for _ in 0..end {
        let frame = host.world.frame();
        let id = match frame {
            10 => Some("old"),
            f if f == end - 100 => Some("new"),
            _ => None,
        };
        if let Some(id) = id {
            let id = Some(id.to_string());
            journal
                .before(Intent::Apply(&press), frame, &sender, &id)
                .unwrap();
            let mut reply = host.handle(&press).reply;
            reply.id = id;
            journal.replied(&reply);
        }
        if frame == end - 50 {
            let step = Command::Server(ServerCommand::Step { n: 1000 });
            let id = Some("steps".to_string());
            journal
                .before(Intent::Apply(&step), frame, &sender, &id)
                .unwrap();
            let mut handled = host.handle(&step);
            step_due = handled.due_at_step;
            handled.reply.id = id;
            journal.replied(&handled.reply);
        }
        host.advance();
        journal.stepped(host.world.frame(), 0.0);
    }
    drop(journal);
    let resumed = resume(&path, &options()).unwrap();
    assert_eq!(resumed.host.stepping.steps_run, host.stepping.steps_run);
    let answered = &resumed.answered;
    assert!(
        answered.get(&sender, "old").is_none(),
        "older than REMEMBER_FOR when the server stopped"
    );
    let new = answered.get(&sender, "new").expect("remembered");
    assert_eq!(new.due_at_step, 0);
    assert!(answered.get(&None, "new").is_none(), "per sender");
    let steps = answered.get(&sender, "steps").expect("remembered");
    assert!(step_due > resumed.host.stepping.steps_run);
    assert_eq!(
        steps.due_at_step, step_due,
        "still running: due when its steps have run"
    );
    assert_eq!(answered.len(), 2);
}

/// A disk that stays full: the lines owed are bounded; past the bound the journal stops
/// at its last whole line, which still resumes, and refuses every command.
#[test]
fn a_journal_owes_at_most_its_bound_then_stops_and_refuses_commands() {
    let mut journal = Journal::full();
    journal.max_owed = 200;
    for frame in 1..=5 {
        journal.stepped(frame, 0.0);
    }
    assert!(
        !journal.stopped && journal.owed.len() > 60,
        "{}",
        journal.owed
    );
    for frame in 6..=20 {
        journal.stepped(frame, 0.0);
    }
    assert!(journal.stopped && journal.owed.is_empty());
    let command = Command::World(ricochet_protocol::command::Action::Deselect);
    let e = journal
        .before(Intent::Apply(&command), 20, &None, &None)
        .unwrap_err();
    assert!(format!("{e:#}").contains("stopped"), "{e:#}");
}
