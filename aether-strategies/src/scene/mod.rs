//! Scene descriptions: Mitsuba 0.5/0.6 XML.
//!
//! [`xml`] reads a file into a tree of plugin declarations with typed
//! properties, resolving `default` and `$param` substitution, `include`
//! and transforms; every error names the file, the line and the element.

mod load;
pub mod xml;

pub use load::{
    Camera, Emitter, Film, FilmTooLarge, GradientSettings, IntegratorSettings, Material,
    MetropolisSettings, MicrofacetKind, Roughness, Scene, Shape, Texture,
};
