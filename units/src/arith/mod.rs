//! Combinational arithmetic: op semantics on raw bits, no host floating point.
