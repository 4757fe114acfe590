use std::path::PathBuf;

use clap::Args;
use lancer::render::{merge_tiles, ExrImage};
use lancer::{Error, Result};

use super::out::{say, Say};

#[derive(Args)]
pub struct MergeCmd {
    /// EXR tiles of one render (`lancer render --crop … -o tile.exr`), in any order.
    #[arg(required = true)]
    tiles: Vec<PathBuf>,
    /// The full image (.exr); never one of the tiles.
    #[arg(short, long)]
    out: PathBuf,
}

impl MergeCmd {
    pub fn run(self) -> Result<()> {
        if !(self.out.extension()).is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
            return Err(Error::input(
                &self.out,
                None,
                "merge writes OpenEXR: use a .exr file name",
            ));
        }
        lancer::output::check_output(&self.out, &self.tiles)?;
        let tiles = (self.tiles.iter())
            .map(|p| Ok((p.clone(), ExrImage::read(p)?)))
            .collect::<Result<Vec<_>>>()?;
        let full = merge_tiles(&tiles)?;
        full.write(&self.out)?;
        say!(
            Say::new(false),
            "{} tiles -> {} ({}x{}, channels {})",
            tiles.len(),
            self.out.display(),
            full.tile.full_width,
            full.tile.full_height,
            (full.channels.iter().map(|c| c.0.as_str()))
                .collect::<Vec<_>>()
                .join(" ")
        );
        Ok(())
    }
}
