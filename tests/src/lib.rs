//! Cross-crate tests (convergence, agreement between integrators, scenes)
//! live in `tests/`; this library holds their shared helpers.
#![deny(unsafe_code)]
