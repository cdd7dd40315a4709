//! Hemicube form factors (Cohen & Greenberg 1985). PLACEHOLDER being written.
