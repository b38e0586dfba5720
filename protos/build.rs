//! Compiles `proto/**/*.proto` with protox (pure Rust, no system `protoc`), generates Rust with
//! prost-build from the resulting descriptor set, and writes the set (without source info) to
//! `OUT_DIR/file_descriptor_set.bin` for `FILE_DESCRIPTOR_SET`.

use prost::Message;
use std::path::{Path, PathBuf};

fn proto_files(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_dir() {
            proto_files(&path, out)?;
        } else if path.extension().is_some_and(|e| e == "proto") {
            out.push(path);
        }
    }
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = PathBuf::from("proto");
    println!("cargo:rerun-if-changed={}", root.display());
    let mut files = Vec::new();
    proto_files(&root, &mut files)?;
    files.sort();
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
    }
    let relative: Vec<PathBuf> =
        files.iter().map(|f| f.strip_prefix(&root).map(Path::to_path_buf)).collect::<Result<_, _>>()?;

    let fds = protox::Compiler::new([&root])?
        .include_imports(true)
        .include_source_info(true)
        .open_files(&relative)?
        .file_descriptor_set();

    let out_dir = PathBuf::from(std::env::var("OUT_DIR")?);
    // The stored set: every file (well-known types included, so a reader needs nothing else),
    // without source info, which only carries comments and would triple the size.
    let mut stored = fds.clone();
    for file in &mut stored.file {
        file.source_code_info = None;
    }
    std::fs::write(out_dir.join("file_descriptor_set.bin"), stored.encode_to_vec())?;

    // Fields of google.protobuf types use prost-types (prost-build's default extern path); the
    // well-known files stay in the set because the generator resolves message types through it.
    prost_build::Config::new()
        // Ordered maps so a message encodes to the same bytes every time (replay determinism).
        .btree_map(["."])
        .compile_fds(fds)?;
    Ok(())
}
