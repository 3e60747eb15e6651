//! The README's measured tables and docs/ figures are what the code produces now
//! (`host-sim readme-figures --check`), and the check catches a table that drifted.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn check(root: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["readme-figures", "--check", "--root", root.to_str().unwrap()])
        .output()
        .expect("host-sim runs")
}

#[test]
fn committed_figures_and_tables_match_the_code() {
    let out = check(&root());
    assert!(
        out.status.success(),
        "README/docs drifted from the code; run `cargo run --release -p host-sim -- readme-figures`\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_drifted_table_fails_the_check() {
    // A copy of what the check reads, with one number in the moves table off by far more than
    // the tolerance.
    let tmp = std::env::temp_dir().join(format!("host-sim-readme-drift-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    for dir in ["docs", "host-sim/params", "host-sim/data"] {
        std::fs::create_dir_all(tmp.join(dir)).unwrap();
        for e in std::fs::read_dir(root().join(dir)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), tmp.join(dir).join(e.file_name())).unwrap();
        }
    }
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let row = readme.lines().find(|l| l.starts_with("| 1 mm, no load")).expect("moves table row");
    let settle = row.split('|').nth(2).unwrap().trim(); // e.g. "0.424 s"
    let secs: f64 = settle.trim_end_matches(" s").parse().unwrap();
    let drifted = row.replacen(settle, &format!("{:.3} s", secs * 1.2), 1);
    std::fs::write(tmp.join("README.md"), readme.replacen(row, &drifted, 1)).unwrap();
    let out = check(&tmp);
    assert!(!out.status.success(), "a 20 % drift passed the check");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("'moves'") && err.lines().count() == 1, "{err}");
    let _ = std::fs::remove_dir_all(&tmp);
}
