//! The text readers users hand files to: machine file, error table, plan,
//! measurement, tool table, `.var`. Invariant: no panic, whatever the bytes;
//! what is accepted holds only finite numbers.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use volcomp::gcode::ToolTable;
use volcomp::inspection::{Measurement, Plan};
use volcomp::machine::table::ErrorTable;
use volcomp::machine::{LoadOptions, Machine};

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(rest) else { return };
    match which % 6 {
        0 => {
            // Tables it names do not exist here: only the TOML layer is reached
            // unless the file is otherwise valid.
            let _ = Machine::parse(text, Path::new("/nonexistent/fuzz.toml"), &LoadOptions::default());
        }
        1 => {
            if let Ok(t) = ErrorTable::parse(text, Path::new("fuzz.csv"), None) {
                assert!(t.positions.iter().all(|p| p.is_finite()));
            }
        }
        2 => {
            if let Ok(p) = Plan::parse(Path::new("fuzz.csv"), text) {
                for q in &p.points {
                    assert!(q.point.iter().chain(&q.normal).all(|v| v.is_finite()));
                }
            }
        }
        3 => {
            let _ = Measurement::parse(Path::new("fuzz.csv"), text);
        }
        4 => {
            if let Ok(t) = ToolTable::parse(text, "fuzz.tbl") {
                assert!(t.entries().all(|e| e.length_mm.is_finite() && e.length_mm >= 0.0));
            }
        }
        _ => {
            let _ = volcomp::gcode::parameters::parse_var_file(text);
        }
    }
});
