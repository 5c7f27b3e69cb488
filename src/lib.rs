//! imagine: facade over the workspace crates.
pub use imagine_hdl as hdl;
pub use imagine_pipelines as pipelines;
pub use imagine_units as units;
pub use imagine_verif as verif;
pub use imagine_waves as waves;
