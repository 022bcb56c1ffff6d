//! Compiles the laparo contract without a system `protoc`.
//!
//! 1. Every `.proto` file under `proto/` is parsed and checked by protox (pure
//!    Rust), which yields a `FileDescriptorSet` with the imported well-known types
//!    and the source comments.
//! 2. That set is encoded to `$OUT_DIR/laparo_descriptor.bin`; `src/lib.rs`
//!    exports it as `FILE_DESCRIPTOR_SET` (gRPC reflection, MCAP schemas).
//! 3. tonic-prost-build generates the prost messages and the tonic clients and
//!    servers from the same set, so the code and the exported descriptors cannot
//!    disagree.

use std::error::Error;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use prost::Message;

/// The include root: files are named relative to it (`laparo/v1/scene.proto`).
const PROTO_ROOT: &str = "proto";

/// Name of the encoded descriptor set in `OUT_DIR`, as `src/lib.rs` includes it.
const DESCRIPTOR_FILE: &str = "laparo_descriptor.bin";

fn main() -> Result<(), Box<dyn Error>> {
    // Cargo scans a directory given here recursively, so new files count too.
    println!("cargo:rerun-if-changed={PROTO_ROOT}");

    let root = Path::new(PROTO_ROOT);
    let mut files = Vec::new();
    collect_protos(root, &mut files)?;
    if files.is_empty() {
        return Err(format!("no .proto file under {}", root.display()).into());
    }
    // A stable order keeps the descriptor set, and so the build, reproducible.
    files.sort();

    // protox's Debug form names the file, line and column of the fault.
    let descriptors = protox::compile(&files, [root]).map_err(|e| format!("{e:?}"))?;

    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").ok_or("OUT_DIR is not set")?);
    fs::write(out_dir.join(DESCRIPTOR_FILE), descriptors.encode_to_vec())?;

    tonic_prost_build::configure()
        .build_client(true)
        .build_server(true)
        .compile_fds(descriptors)?;
    Ok(())
}

/// Appends every `.proto` file under `dir`, recursively, to `files`.
fn collect_protos(dir: &Path, files: &mut Vec<PathBuf>) -> io::Result<()> {
    for entry in fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_dir() {
            collect_protos(&path, files)?;
        } else if path.extension().is_some_and(|ext| ext == "proto") {
            files.push(path);
        }
    }
    Ok(())
}
