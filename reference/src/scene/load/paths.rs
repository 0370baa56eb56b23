//! Every file the loaders read is read here: path confinement and the file-reading helpers.
//!
//! Contract:
//! - **Files under the scene's folder** (module docs): a path a scene file names is resolved
//!   against the scene file's folder and, unless [`LoadOptions::allow_outside_paths`], must lie
//!   under it after resolving `..` and symbolic links (`resolve_named`, `confine`); a path that
//!   does not resolve is returned as is, and reading it reports it;
//! - whole files are read with `read_limited`, which refuses a file of more than its limit
//!   ([`MAX_SCENE_FILE_BYTES`], [`MAX_MESH_FILE_BYTES`], [`MAX_TEXTURE_FILE_BYTES`]); the
//!   instance table is streamed (`open_file`), bounded by its row and record limits instead;
//! - only regular files are read (after resolving links): a FIFO, a socket, a device or a link
//!   to one is refused before it is opened, naming the file (issue 28);
//! - a file that cannot be opened or read is an [`InputError`] at position `file`, value the
//!   file's name, reason `cannot be read: ...`; `label` is how every error names a file.
//!
//! The lowest file of the loaders: it imports none of the others.

use std::path::{Path, PathBuf};

use crate::InputError;

/// Largest scene file accepted, bytes.
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 20;
/// Largest OBJ file accepted, bytes (a < 20-triangle tree needs a few kilobytes).
pub const MAX_MESH_FILE_BYTES: u64 = 4 << 20;
/// Largest PNG file accepted, bytes.
pub const MAX_TEXTURE_FILE_BYTES: u64 = 256 << 20;

/// How a scene file may name other files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Allow the files a scene file names (instances, meshes, textures, glTF buffers) to lie
    /// outside the scene file's folder (after resolving `..` and symbolic links). Off by default:
    /// a scene file from elsewhere cannot make the loader read arbitrary files (the CLI's
    /// `--allow-outside-paths`).
    pub allow_outside_paths: bool,
}

pub(super) fn label(path: &Path) -> String {
    path.display().to_string()
}

/// Reads a whole file of at most `limit` bytes: [`crate::files::read_limited`] (regular files
/// only, the size checked before reading).
pub(super) fn read_limited(path: &Path, limit: u64) -> Result<Vec<u8>, InputError> {
    crate::files::read_limited(path, limit)
}

/// Opens a file to be streamed (the instance table, read record by record and bounded by its
/// row and record limits, not by a size): a regular file only ([`crate::files::regular_file`]).
pub(super) fn open_file(path: &Path) -> Result<std::fs::File, InputError> {
    crate::files::open_limited(path, u64::MAX).map(|(f, _)| f)
}

/// The scene file's folder as relative paths start from it (empty for a bare file name, so that
/// named files keep the names they were given in errors).
pub(super) fn scene_folder(path: &Path) -> &Path {
    path.parent().unwrap_or(Path::new(""))
}

/// Where a path named in a scene file points: `base.join(named)`, checked to lie under `base`
/// (after resolving `..` and symbolic links) unless `options` allow otherwise. A path that does
/// not resolve (a missing file) is returned as is: reading it reports it. `link` is the naming
/// field (`scene.toml: line 2, column 13, field instances`).
pub(super) fn resolve_named(
    base: &Path,
    named: &str,
    options: &LoadOptions,
    file: &str,
    position: &str,
) -> Result<PathBuf, InputError> {
    confine(base, base.join(named), named, options, file, position)
}

/// `path` (written `named` in `file` at `position`) if it lies under `root` after resolving `..`
/// and symbolic links, or `options` allow files outside; a path that does not resolve is
/// returned as is (reading it reports it).
pub(super) fn confine(
    root: &Path,
    path: PathBuf,
    named: &str,
    options: &LoadOptions,
    file: &str,
    position: &str,
) -> Result<PathBuf, InputError> {
    if options.allow_outside_paths {
        return Ok(path);
    }
    let root = if root.as_os_str().is_empty() {
        Path::new(".")
    } else {
        root
    };
    if let (Ok(root), Ok(target)) = (root.canonicalize(), path.canonicalize())
        && !target.starts_with(&root)
    {
        return Err(InputError::new(
            file,
            position,
            named,
            format!(
                "resolves to {}, outside the scene file's folder {}: move the file under that folder, or allow it (--allow-outside-paths)",
                target.display(),
                root.display()
            ),
        ));
    }
    Ok(path)
}
