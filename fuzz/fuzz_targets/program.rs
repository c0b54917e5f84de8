//! Reader + interpreter + rewriter: any bytes as a program, with a tool table.
//! Invariants: no panic; a program volcomp compensates or flattens reads back
//! through volcomp without error, and compensating it again is refused only
//! by the stamp (the library has none), i.e. the output is a valid program.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;
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
        e.motion.as_ref().map(|m| m.end)
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
    let mut out = Vec::new();
    if compensate(program(data), &mut out, &model, &CompensateOptions::default(), |_| {}).is_ok() {
        if let Err(e) = runs(&out) {
            panic!("compensated program does not read back: {e}\n{}", String::from_utf8_lossy(&out));
        }
    }
});
