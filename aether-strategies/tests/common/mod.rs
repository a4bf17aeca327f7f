//! Helpers shared by the scene-layer tests.

use std::path::{Path, PathBuf};

/// The Aether example scenes beside the project, or `None` (said on
/// stderr) in a clone without them.
pub fn scenes() -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes/aether");
    if p.is_dir() {
        Some(p)
    } else {
        eprintln!("{} is absent: the example scenes are not used", p.display());
        None
    }
}
