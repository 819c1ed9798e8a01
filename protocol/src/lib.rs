//! Ricochet's data formats shared by the server and the tools that read its output.
//!
//! Today: [`dump`], the JSON Lines frames written by `ricochet-server simulate --dump`.

pub mod dump;
