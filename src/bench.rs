//! `skyrender bench`: speed and noise measurements (placeholder until written).

/// Options of `skyrender bench`.
#[derive(clap::Args, Debug, Clone)]
pub struct BenchArgs {
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(_args: &BenchArgs) -> Result<(), String> {
    Err("bench: not available yet".into())
}
