//! The measuring commands of `ricochet-server`: scenes and settings flow in; figures
//! (tables, CSV, charts) flow out. Nothing here is on the server's hot path.
//!
//! - [`bench`]: what a step costs, per case and setting;
//! - [`tradeoff`]: what each solver setting costs and buys in accuracy.

pub mod bench;
pub mod tradeoff;
