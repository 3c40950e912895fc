//! `windcell`: the filament-winding cell coordinator.
fn main() {
    println!("windcell");
}
