//! `example_data`: converts the example scene's real data (issue 34, item 3) from the unpacked
//! Debian package into a scene folder (`forestlod_experiments::example_data` says what and how).
//! `scripts/fetch-example-data` fetches, checks and unpacks the package, then runs this:
//!
//! ```sh
//! cargo run --release -p forestlod-experiments --bin example_data -- \
//!     --package-root target/example-data/r-cran-spatstat.data_3.0-0-1 --out target/example-data/bci
//! cargo run --release -p forestlod-experiments --bin example_data -- \
//!     --package-root ... --window 600,200,800,400 --out target/example-data/bci-cut
//! ```
//!
//! Prints one line: trees, DEM size, extent and relief. Exit 1 with the error on bad input.

use std::path::PathBuf;

use clap::Parser;
use forestlod_experiments::example_data::{DATA_DIR_IN_PACKAGE, Window, read_bei, write_scene};

#[derive(Parser)]
#[command(about = "Convert the BCI Beilschmiedia census and its DEM into a forestlod scene")]
struct Args {
    /// The folder the Debian package was unpacked into (`dpkg-deb -x`).
    #[arg(long)]
    package_root: PathBuf,
    /// The scene folder to write (`bei.toml`, `dem.asc`, `trees.csv`).
    #[arg(long)]
    out: PathBuf,
    /// Only this part of the plot: x_min,y_min,x_max,y_max in the plot's metres.
    #[arg(long)]
    window: Option<Window>,
}

fn main() {
    let a = Args::parse();
    let run = || -> Result<String, Box<dyn std::error::Error>> {
        let (census, elev) = read_bei(&a.package_root.join(DATA_DIR_IN_PACKAGE))?;
        let w = write_scene(&census, &elev, a.window, &a.out)?;
        Ok(format!(
            "{}: {} trees; DEM {}x{} samples at {} m over x {}..{} m, y {}..{} m, heights {}..{} m (relief {:.2} m)",
            a.out.join("bei.toml").display(),
            w.trees,
            w.dem_size[0],
            w.dem_size[1],
            elev.step,
            w.dem_extent[0],
            w.dem_extent[2],
            w.dem_extent[1],
            w.dem_extent[3],
            w.relief[0],
            w.relief[1],
            w.relief[1] - w.relief[0]
        ))
    };
    match run() {
        Ok(line) => println!("{line}"),
        Err(e) => {
            eprintln!("example_data: {e}");
            std::process::exit(1);
        }
    }
}
