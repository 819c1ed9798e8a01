//! What proving a sender costs (divan): `cargo bench -p ricochet-lab --bench identity`.
//!
//! A client signs each message it sends; the server checks each signed claim of a
//! connected session on zenoh's receive threads (`ricochet_protocol::identity`).

use ricochet_protocol::identity::{Identity, Proof};

fn main() {
    divan::main();
}

const KEY: &str = "ricochet/default/rpc";
const COMMAND: &[u8] =
    br#"{"do":"impulse","body":"ball","impulse":[40,0],"id":"r0123456789abcdef0123456789abcdef"}"#;

/// Signing one command (the client's cost per message).
#[divan::bench]
fn sign(bencher: divan::Bencher) {
    let me = Identity::generate();
    bencher.bench_local(|| me.sign(KEY, divan::black_box(COMMAND)));
}

/// Checking one signed command (the server's cost per signed claim).
#[divan::bench]
fn verify(bencher: divan::Bencher) {
    let me = Identity::generate();
    let proof = Proof::read(&me.sign(KEY, COMMAND)).expect("an attachment");
    bencher.bench_local(|| assert!(proof.verify(KEY, divan::black_box(COMMAND))));
}

/// The checks before the signature: reading the attachment and deriving the id its key names.
#[divan::bench]
fn read_and_derive_the_id(bencher: divan::Bencher) {
    let attachment = Identity::generate().sign(KEY, COMMAND);
    bencher.bench_local(|| {
        Proof::read(divan::black_box(&attachment))
            .expect("an attachment")
            .zid()
    });
}
