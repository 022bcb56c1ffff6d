//! Whether the embedded console bundle (`web/dist`) was built from the sources in
//! the tree.
//!
//! `npm --prefix web run build` writes `web/dist/bundle-hash.txt`: the SHA-256 of
//! the build's inputs — the page's sources (`web/src`, less the code generated
//! from the contract), `web/index.html`, the package and lock files, the build
//! configuration, and the contract (`proto/proto`, from which the client code is
//! generated). [`inputs_hash`] computes the same from a checkout, so a test fails
//! when someone changes a source or the contract and does not rebuild.
//!
//! The hash: files sorted by their path relative to the repository root (`/`
//! separators); for each, the path, a NUL, the length in decimal, a NUL, the
//! bytes. `web/scripts/stamp.mjs` is the other implementation.

use std::io;
use std::path::Path;

use sha2::{Digest, Sha256};

/// The command that rebuilds the bundle (and its stamp): the packages installed
/// from the committed lock as `.ci/run` installs them (`npm ci` refuses a lock that
/// lacks other platforms' builds of buf, which this project's registry does not
/// list), the lock kept as committed (the stamp covers it), then the build.
pub const REBUILD: &str = "npm --prefix web install --no-audit --no-fund && git checkout web/package-lock.json && npm --prefix web run build";

/// Single files among the inputs, relative to the repository root.
pub const INPUT_FILES: [&str; 7] = [
    "web/index.html",
    "web/package.json",
    "web/package-lock.json",
    "web/tsconfig.json",
    "web/vite.config.ts",
    "web/buf.gen.yaml",
    "web/scripts/stamp.mjs",
];
/// Directories whose files are inputs, every depth.
pub const INPUT_DIRS: [&str; 2] = ["web/src", "proto/proto"];
/// Generated from `proto/proto` by the build: not an input itself.
pub const GENERATED_DIR: &str = "web/src/gen";

/// The hash of the bundle's inputs in the checkout at `root`, lowercase hex.
pub fn inputs_hash(root: &Path) -> io::Result<String> {
    let mut files: Vec<String> = INPUT_FILES.iter().map(|f| f.to_string()).collect();
    for dir in INPUT_DIRS {
        collect(root, dir, &mut files)?;
    }
    files.sort();
    let mut hasher = Sha256::new();
    for file in &files {
        let bytes = std::fs::read(root.join(file))
            .map_err(|e| io::Error::new(e.kind(), format!("{file}: {e}")))?;
        hasher.update(file.as_bytes());
        hasher.update([0]);
        hasher.update(bytes.len().to_string().as_bytes());
        hasher.update([0]);
        hasher.update(&bytes);
    }
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// The files under `dir` (relative to `root`), but not under [`GENERATED_DIR`].
fn collect(root: &Path, dir: &str, out: &mut Vec<String>) -> io::Result<()> {
    if dir == GENERATED_DIR {
        return Ok(());
    }
    for entry in std::fs::read_dir(root.join(dir))? {
        let entry = entry?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let path = format!("{dir}/{name}");
        if entry.file_type()?.is_dir() {
            collect(root, &path, out)?;
        } else {
            out.push(path);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_console_is_built_from_the_sources_in_the_tree() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let now = inputs_hash(&root).expect("the console's sources are readable");
        let stamp = std::fs::read_to_string(root.join("web/dist/bundle-hash.txt"))
            .unwrap_or_else(|e| panic!("web/dist/bundle-hash.txt: {e}; build it with `{REBUILD}`"));
        assert_eq!(
            stamp.trim(),
            now,
            "the console bundle in web/dist is stale against web/ and proto/: rebuild it with `{REBUILD}` and commit web/dist"
        );
    }
}
