//! imagine-verif: golden models, testbenches, reference renderer and image metrics
//! (ARCHITECTURE §6).

pub mod testfloat;
