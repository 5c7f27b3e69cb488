//! imagine-waves: VCD output for the probe registry of `imagine-hdl`.
