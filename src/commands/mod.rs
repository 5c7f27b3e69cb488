//! One module per subcommand.

pub mod demo;
pub mod pending;
pub mod render;
pub mod verify;
pub mod waves;
