//! One module per subcommand.

pub mod bench;
pub mod compare;
pub mod datapath;
pub mod demo;
pub mod dram;
pub mod kernel;
pub mod machine;
pub mod outputs;
pub mod reference_error;
pub mod render;
pub mod render_reyes;
pub mod s3;
pub mod scene;
pub mod stress;
pub mod sweep;
pub mod verify;
pub mod waves;
