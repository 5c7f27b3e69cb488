//! imagine-hdl: the RTL vocabulary (ARCHITECTURE §3).
