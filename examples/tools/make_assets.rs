//! Writes the sandbox's built-in models to `assets/models/*.obj` (generated, not modelled).
//!
//! ```text
//! cargo run --release --example make_assets
//! ```

use bevy_wii_deform_examples::cli;
use bevy_wii_deform_examples::models;

const USAGE: &str = "usage: make_assets (writes assets/models/{bar,cactus,mannequin}.obj)";

fn main() {
    let mut parser = cli::Parser::from_env();
    if let Some(arg) = cli::next(&mut parser, USAGE) {
        cli::unexpected(arg, USAGE);
    }
    std::fs::create_dir_all("assets/models").expect("create assets/models");
    for name in models::MODELS {
        let mesh = models::generate(name).expect("built-in model");
        let path = format!("assets/models/{name}.obj");
        std::fs::write(&path, mesh.to_obj()).expect("write model");
        println!(
            "{path}: {} vertices, {} triangles",
            mesh.positions.len(),
            mesh.triangles.len()
        );
    }
}
