//! imagine-pipelines: kernel IR, interpreter, compiler to microcode, stream programs,
//! rendering pipelines and scenes (ARCHITECTURE §5).

pub mod compile;
pub mod kernel;
pub mod kernels;
pub mod opengl;
pub mod reyes;
pub mod run;
pub mod scene;
pub mod stream;
