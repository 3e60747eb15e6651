//! `host-sim readme-figures`' flags ([`ReadmeFiguresOptions`]).

use host_sim::readme_figures::ReadmeFiguresOptions;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ReadmeFiguresArgs {
    /// Compare with the committed figures and the tables in README.md and docs/*.md instead of
    /// writing them; exit non-zero on drift.
    #[arg(long)]
    pub check: bool,
    /// Repository root: where README.md, docs/ and host-sim/ are.
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub root: PathBuf,
}

impl From<ReadmeFiguresArgs> for ReadmeFiguresOptions {
    fn from(a: ReadmeFiguresArgs) -> Self {
        ReadmeFiguresOptions { check: a.check, root: a.root }
    }
}
