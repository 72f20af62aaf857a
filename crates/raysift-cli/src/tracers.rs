//! `raysift tracers`: the registered tracers.

use anyhow::Result;
use raysift::tracers;

pub fn run() -> Result<()> {
    for n in tracers::names() {
        println!("{n}");
    }
    Ok(())
}
