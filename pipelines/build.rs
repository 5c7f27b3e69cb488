//! The compiler's fingerprint for the compile cache (`src/compile/cache.rs`): a BLAKE3
//! hash of the sources that decide what microcode a kernel compiles to (the compiler, the
//! kernel IR, and the microcode format in `imagine-units`), exported as
//! `IMAGINE_COMPILER_FINGERPRINT`. Any edit to them gives new cache keys, so a changed
//! compiler never reads microcode an older one wrote.

use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    if dir.is_file() {
        out.push(dir.to_path_buf());
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let roots = [
        ("pipelines/compile", manifest.join("src/compile")),
        ("pipelines/kernel", manifest.join("src/kernel")),
        ("units/microcode", manifest.join("../units/src/microcode")),
        // The ops' unit classes and the description's fields.
        ("units/ops", manifest.join("../units/src/ops.rs")),
        ("units/desc", manifest.join("../units/src/desc.rs")),
    ];
    let mut hasher = blake3::Hasher::new();
    for (label, root) in &roots {
        println!("cargo:rerun-if-changed={}", root.display());
        let mut list = Vec::new();
        files(root, &mut list);
        list.sort();
        hasher.update(label.as_bytes());
        hasher.update(&(list.len() as u64).to_le_bytes());
        for path in list {
            let rel = path.strip_prefix(root).unwrap_or(&path);
            let name = rel.to_string_lossy().replace('\\', "/");
            let text = std::fs::read(&path).unwrap_or_default();
            hasher.update(&(name.len() as u64).to_le_bytes());
            hasher.update(name.as_bytes());
            hasher.update(&(text.len() as u64).to_le_bytes());
            hasher.update(&text);
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
    println!(
        "cargo:rustc-env=IMAGINE_COMPILER_FINGERPRINT={}",
        hasher.finalize().to_hex()
    );
}
