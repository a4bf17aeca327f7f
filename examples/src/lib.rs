//! Short programs that reproduce the Aether examples; see `examples/`.
#![deny(unsafe_code)]
