//! Reader + interpreter + rewriter: any bytes as a program, with a tool table.
//! Invariants: no panic; a program volcomp compensates or flattens reads back
//! through volcomp without error, the compensated one written through the
//! stamp writer as `volcomp compensate` writes it (and its stamp found again).
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use volcomp::compensate::stamp::{Stamp, StampWriter};
use volcomp::compensate::{CompensateOptions, compensate};
use volcomp::gcode::{InterpretOptions, Program, ProgramSetup, RewriteOptions, ToolTable, rewrite_stream};
use volcomp::kinematics::{ErrorValues, Geometry, Kinematics};
use volcomp::machine::ErrorModel;

fn setup() -> ProgramSetup {
    ProgramSetup {
        tools: ToolTable::parse("T1 P1 Z40 D10\nT2 P2 Z120 D6\n", "fuzz.tbl").unwrap(),
        // Endless loops end as an error, quickly.
        language: volcomp::gcode::LanguageOptions {
            max_executed_lines: Some(100_000),
            ..Default::default()
        },
        ..ProgramSetup::default()
    }
}

fn program(bytes: &[u8]) -> Program {
    Program::new(Box::new(std::io::Cursor::new(bytes.to_vec())), Path::new("fuzz.ngc"), setup())
}

/// Run `bytes` to the end; whether it was accepted.
fn runs(bytes: &[u8]) -> Result<(), String> {
    let mut run = program(bytes).run(InterpretOptions::default());
    while let Some(step) = run.next() {
        step.map_err(|e| e.to_string())?;
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    if runs(data).is_err() {
        return;
    }
    // Flattened: reads back.
    let mut flat = Vec::new();
    if rewrite_stream(program(data).run(InterpretOptions::default()), &mut flat, RewriteOptions::default(), |_, e, _| {
        e.motion().map(|m| m.end)
    })
    .is_ok()
    {
        if let Err(e) = runs(&flat) {
            panic!("flattened program does not read back: {e}\n{}", String::from_utf8_lossy(&flat));
        }
    }
    // Compensated with a model of position-independent errors (no fit): reads back.
    let mut scalars = ErrorValues::ZERO;
    scalars.squareness = [20.0, -15.0, 10.0];
    scalars.location[0] = 5.0;
    let model = ErrorModel::scalars_only(Kinematics::new(Geometry::default(), 100.0), scalars);
    // Through the stamp writer, as `volcomp compensate` writes it: the stamp
    // must not break the program (issue 23: before a `%` behind blank lines).
    let mut out = Vec::new();
    let written = {
        let mut stamped = StampWriter::new(&mut out, stamp());
        compensate(program(data), &mut stamped, &model, &CompensateOptions::default(), |_| {}).is_ok()
            && stamped.finish().is_ok()
    };
    if written {
        if let Err(e) = runs(&out) {
            panic!("compensated program does not read back: {e}\n{}", String::from_utf8_lossy(&out));
        }
        assert!(Stamp::find(&String::from_utf8_lossy(&out)).is_some(), "the stamp is not found again");
    }
});

fn stamp() -> Stamp {
    Stamp {
        compensated_by: "volcomp fuzz".into(),
        machine: "fuzz".into(),
        model_fnv1a64: "0123456789abcdef".into(),
        model_source: "scalars".into(),
        tool_length_mm: Some(100.0),
        tools_mm: "T1=40 T2=120".into(),
        tolerance_um: Some(0.5),
        input: "fuzz.ngc".into(),
        input_fnv1a64: "0123456789abcdef".into(),
        orientation: true,
    }
}
