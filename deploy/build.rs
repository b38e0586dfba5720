//! Stamps the binary with the commit it was built from (`RISKTWIN_COMMIT`, recorded in every
//! deployment report): `RISKTWIN_COMMIT` if the build is given one, else the checkout's HEAD,
//! else "unknown". Rebuilt when the checkout's HEAD moves.

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    let text = String::from_utf8(out.stdout).ok()?;
    out.status.success().then(|| text.trim().to_owned()).filter(|t| !t.is_empty())
}

fn main() {
    // A build without the checkout (a container, a source archive) may say it.
    println!("cargo:rerun-if-env-changed=RISKTWIN_COMMIT");
    let given = std::env::var("RISKTWIN_COMMIT").ok().filter(|c| !c.is_empty());
    let commit = given.or_else(|| git(&["rev-parse", "HEAD"])).unwrap_or_else(|| "unknown".to_owned());
    println!("cargo:rustc-env=RISKTWIN_COMMIT={commit}");
    // HEAD's log is written by every commit, checkout and reset (also when the branch's ref is
    // packed); HEAD, the branch it names and the packed refs in case the log is off.
    let mut watched = vec!["logs/HEAD".to_owned(), "HEAD".to_owned(), "packed-refs".to_owned()];
    watched.extend(git(&["symbolic-ref", "-q", "HEAD"]));
    for path in watched {
        // A path that does not exist would make cargo run this on every build.
        if let Some(file) = git(&["rev-parse", "--git-path", &path]).filter(|f| std::path::Path::new(f).exists()) {
            println!("cargo:rerun-if-changed={file}");
        }
    }
}
