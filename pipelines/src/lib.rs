//! imagine-pipelines: kernel IR, interpreter, compiler to microcode, stream programs,
//! rendering pipelines and scenes (ARCHITECTURE §5).
