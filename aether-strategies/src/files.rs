//! Opening the files a scene names (scene files, includes, meshes, material
//! libraries, textures): only regular files, and only up to a size bound,
//! so that a device (`/dev/zero`, `/dev/urandom`), a pipe or a directory
//! given as a mesh is an error that names it, not a read that never ends.

use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// The largest scene file or include read: far beyond any written by hand
/// or exported, small enough to hold in memory.
pub const MAX_SCENE_BYTES: u64 = 256 << 20;
/// The largest mesh file read (OBJ or `.serialized`).
pub const MAX_MESH_BYTES: u64 = 4 << 30;
/// The largest material library or texture read.
pub const MAX_IMAGE_BYTES: u64 = 1 << 30;

/// Why a file a scene names cannot be read.
#[derive(Debug)]
pub enum FileError {
    /// Nothing is at the path.
    Missing(PathBuf),
    /// The path is a directory.
    Directory(PathBuf),
    /// The path is a device, a pipe or a socket.
    NotRegular(PathBuf),
    /// The file is larger than its kind may be.
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size in bytes.
        size: u64,
        /// The bound for its kind.
        limit: u64,
    },
    /// The system refused to open or read it.
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

impl FileError {
    /// The file the error is about.
    #[must_use]
    pub fn path(&self) -> &Path {
        match self {
            FileError::Missing(p) | FileError::Directory(p) | FileError::NotRegular(p) => p,
            FileError::TooLarge { path, .. } | FileError::Io { path, .. } => path,
        }
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.path().display();
        match self {
            FileError::Missing(_) => write!(f, "{p} does not exist"),
            FileError::Directory(_) => write!(f, "{p} is a directory, not a file"),
            FileError::NotRegular(_) => write!(
                f,
                "{p} is not a regular file (a device, a pipe or a socket is not read)"
            ),
            FileError::TooLarge { size, limit, .. } => write!(
                f,
                "{p} is {size} bytes, over the {limit} bytes a file of its kind may have"
            ),
            FileError::Io { source, .. } => write!(f, "{p} cannot be read: {source}"),
        }
    }
}

impl std::error::Error for FileError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            FileError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Checks that `path` is a regular file of at most `limit` bytes, and
/// returns its size.
///
/// # Errors
/// If it is missing, not a regular file, too large or unreadable.
pub fn check_regular(path: &Path, limit: u64) -> Result<u64, FileError> {
    let meta = std::fs::metadata(path).map_err(|source| match source.kind() {
        std::io::ErrorKind::NotFound => FileError::Missing(path.to_owned()),
        _ => FileError::Io {
            path: path.to_owned(),
            source,
        },
    })?;
    if meta.is_dir() {
        return Err(FileError::Directory(path.to_owned()));
    }
    if !meta.is_file() {
        return Err(FileError::NotRegular(path.to_owned()));
    }
    if meta.len() > limit {
        return Err(FileError::TooLarge {
            path: path.to_owned(),
            size: meta.len(),
            limit,
        });
    }
    Ok(meta.len())
}

/// Opens a regular file of at most `limit` bytes for buffered reading; the
/// reader stops at `limit` even if the file grows meanwhile.
///
/// # Errors
/// As [`check_regular`], or if it cannot be opened.
pub fn open_regular(path: &Path, limit: u64) -> Result<BufReader<std::io::Take<File>>, FileError> {
    check_regular(path, limit)?;
    let file = File::open(path).map_err(|source| FileError::Io {
        path: path.to_owned(),
        source,
    })?;
    Ok(BufReader::new(file.take(limit)))
}

/// Reads a whole regular file of at most `limit` bytes.
///
/// # Errors
/// As [`open_regular`], or if reading fails.
pub fn read_regular(path: &Path, limit: u64) -> Result<Vec<u8>, FileError> {
    let size = check_regular(path, limit)?;
    let mut bytes = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    open_regular(path, limit)?
        .read_to_end(&mut bytes)
        .map_err(|source| FileError::Io {
            path: path.to_owned(),
            source,
        })?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_the_bound_are_read() {
        let dir = std::env::temp_dir().join(format!("aether-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("a.txt");
        std::fs::write(&file, b"0123456789").unwrap();
        assert_eq!(read_regular(&file, 10).unwrap(), b"0123456789");
        assert!(matches!(
            read_regular(&file, 9),
            Err(FileError::TooLarge { size: 10, .. })
        ));
        assert!(matches!(
            read_regular(&dir, 10),
            Err(FileError::Directory(_))
        ));
        let missing = dir.join("none");
        assert!(matches!(
            read_regular(&missing, 10),
            Err(FileError::Missing(_))
        ));
        if Path::new("/dev/zero").exists() {
            let e = read_regular(Path::new("/dev/zero"), 10).unwrap_err();
            assert!(matches!(e, FileError::NotRegular(_)));
            assert!(e.to_string().contains("/dev/zero"), "{e}");
        }
    }
}
