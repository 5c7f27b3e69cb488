//! imagine-verif: golden models, testbenches, reference renderer and image metrics
//! (ARCHITECTURE §6).

pub mod blocks;
pub mod bump_env;
pub mod image;
pub mod marble;
#[cfg(feature = "osmesa")]
pub mod osmesa;
pub mod reference;
pub mod reference_model;
pub mod stress;
pub mod testfloat;
