//! The language front of a run, one per dialect: what [`super::Execution`]
//! reads executed blocks from. An enum, not a trait object: the LinuxCNC
//! path pays one predictable branch per block.
//!
//! A front hands on executed blocks (a [`Block`] whose words the
//! machine-state layer reads, with the source line's raw bytes so that
//! writers copy an untouched line byte for byte, and [`Executed`]: where it
//! comes from). A dialect whose control keeps state LinuxCNC's interpreter
//! does not (frames, swivelled planes) sets it on the [`Interpreter`] before
//! the block is interpreted (`Interpreter::set_frame`, `set_position`).
//! A front that keeps its own machine state (Heidenhain's) gives its blocks
//! their meaning itself ([`Front::interpret`], [`Front::pass_over`]); the
//! others are interpreted by LinuxCNC's [`Interpreter`]. A further dialect
//! adds a variant here and its folder beside `sinumerik/` and `heidenhain/`.
use std::path::Path;

use crate::gcode::dialect::{Dialect, DialectChoice};
use crate::gcode::error::GcodeError;
use crate::gcode::language::{Executed, Executor, LanguageOptions, ProgramInput};
use crate::gcode::machine::interpret::Interpreter;
use crate::gcode::syntax::block::Block;

/// The language front of one run. The LinuxCNC executor is held inline
/// (no indirection on its per-block path); the dialect fronts are boxed;
/// there is one front per run.
#[allow(clippy::large_enum_variant)]
pub(crate) enum Front {
    /// LinuxCNC's language layer (O-words, parameters, subroutine files).
    LinuxCnc(Executor),
    /// SINUMERIK 840D sl (`gcode::sinumerik`): its language feeds LinuxCNC's
    /// interpreter (frames and positions set on it).
    Sinumerik(Box<crate::gcode::sinumerik::SinumerikFront>),
    /// Heidenhain Klartext (`gcode::heidenhain`): its own language and
    /// machine state, which give each block's event themselves
    /// ([`Front::interpret`]).
    Heidenhain(Box<crate::gcode::heidenhain::KlartextFront>),
}

impl Front {
    /// The front for `choice`, reading `input` named `path`.
    pub(crate) fn new(
        choice: &DialectChoice,
        input: Box<dyn ProgramInput>,
        path: &Path,
        language: LanguageOptions,
        options: &crate::gcode::InterpretOptions,
        setup: &crate::gcode::ProgramSetup,
    ) -> Front {
        match choice.dialect {
            Dialect::LinuxCnc => Front::LinuxCnc(Executor::new(input, path, language)),
            Dialect::Sinumerik => Front::Sinumerik(Box::new(
                crate::gcode::sinumerik::SinumerikFront::new(input, path, language, setup),
            )),
            Dialect::Heidenhain => {
                Front::Heidenhain(Box::new(crate::gcode::heidenhain::KlartextFront::new(
                    input, path, &language, options, setup,
                )))
            }
        }
    }

    /// The next executed block (then [`Front::block`]), `None` at the end.
    #[inline]
    pub(crate) fn next_block(
        &mut self,
        interpreter: &mut Interpreter,
    ) -> Option<Result<(), GcodeError>> {
        match self {
            Front::LinuxCnc(e) => e.next_block(interpreter.parameters_mut()),
            Front::Sinumerik(s) => s.next_block(interpreter),
            Front::Heidenhain(h) => h.next_block(),
        }
    }

    /// The last executed block.
    #[inline]
    pub(crate) fn block(&self) -> &Block {
        match self {
            Front::LinuxCnc(e) => e.block(),
            Front::Sinumerik(s) => s.block(),
            Front::Heidenhain(h) => h.block(),
        }
    }

    /// Where the last executed block came from.
    #[inline]
    pub(crate) fn executed(&self) -> &Executed {
        match self {
            Front::LinuxCnc(e) => e.executed(),
            Front::Sinumerik(s) => s.executed(),
            Front::Heidenhain(h) => h.executed(),
        }
    }

    /// Name of file `index` (0: the main program).
    pub(crate) fn file_name(&self, index: usize) -> &str {
        match self {
            Front::LinuxCnc(e) => e.file_name(index),
            Front::Sinumerik(s) => s.file_name(index),
            Front::Heidenhain(h) => h.file_name(index),
        }
    }

    /// The machine-state layer saw the program's end.
    pub(crate) fn end_program(&mut self) {
        match self {
            Front::LinuxCnc(e) => e.end_program(),
            Front::Sinumerik(s) => s.end_program(),
            Front::Heidenhain(h) => h.end_program(),
        }
    }

    /// After the end: the next line of the main file as written.
    pub(crate) fn next_tail_line(&mut self) -> Option<Result<(), GcodeError>> {
        match self {
            Front::LinuxCnc(e) => e.next_tail_line(),
            Front::Sinumerik(s) => s.next_tail_line(),
            Front::Heidenhain(h) => h.next_tail_line(),
        }
    }

    /// The program ended at a closing `%`.
    pub(crate) fn percent_ended(&self) -> bool {
        match self {
            Front::LinuxCnc(e) => e.percent_ended(),
            Front::Sinumerik(s) => s.percent_ended(),
            Front::Heidenhain(_) => false,
        }
    }

    /// Lines read from the main program so far.
    pub(crate) fn lines_read(&self) -> usize {
        match self {
            Front::LinuxCnc(e) => e.lines_read(),
            Front::Sinumerik(s) => s.lines_read(),
            Front::Heidenhain(h) => h.lines_read(),
        }
    }

    /// The product of the counts of the counted loops being run.
    pub(crate) fn repeat_trips(&self) -> f64 {
        match self {
            Front::LinuxCnc(e) => e.repeat_trips(),
            Front::Sinumerik(_) | Front::Heidenhain(_) => 1.0,
        }
    }

    /// The innermost loop being run, as messages name it.
    pub(crate) fn innermost_loop(&self) -> Option<String> {
        match self {
            Front::LinuxCnc(e) => e.innermost_loop(),
            Front::Sinumerik(s) => s.innermost_loop(),
            Front::Heidenhain(h) => h.in_call().then(|| "a CALL LBL / CALL PGM".to_string()),
        }
    }

    /// Give the block just handed on its meaning: LinuxCNC's interpreter,
    /// or a dialect front that keeps its own machine state.
    #[inline]
    pub(crate) fn interpret(
        &mut self,
        interpreter: &mut Interpreter,
        event: &mut crate::gcode::BlockEvent,
    ) -> Result<(), GcodeError> {
        match self {
            Front::LinuxCnc(e) => interpreter.interpret_into(e.block(), event),
            Front::Sinumerik(s) => interpreter.interpret_into(s.block(), event),
            Front::Heidenhain(h) => h.interpret(event),
        }
    }

    /// The event of a block handed on as written, not run.
    #[inline]
    pub(crate) fn pass_over(
        &self,
        interpreter: &Interpreter,
        event: &mut crate::gcode::BlockEvent,
    ) {
        match self {
            Front::LinuxCnc(e) => interpreter.pass_over(e.block(), event),
            Front::Sinumerik(s) => interpreter.pass_over(s.block(), event),
            Front::Heidenhain(h) => h.pass_over(event),
        }
    }
}
