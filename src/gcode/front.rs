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
//! A third dialect adds a variant here and its folder beside `sinumerik/`.
use std::path::Path;

use crate::gcode::dialect::{Dialect, DialectChoice};
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::language::{Executed, Executor, LanguageOptions, ProgramInput};
use crate::gcode::machine::interpret::Interpreter;
use crate::gcode::syntax::block::Block;

/// The language front of one run. The LinuxCNC executor is held inline
/// (no indirection on its per-block path); there is one front per run.
#[allow(clippy::large_enum_variant)]
pub(crate) enum Front {
    /// LinuxCNC's language layer (O-words, parameters, subroutine files).
    LinuxCnc(Executor),
    /// SINUMERIK 840D sl (`gcode::sinumerik`).
    Sinumerik(Box<crate::gcode::sinumerik::SinumerikFront>),
    /// A dialect volcomp does not read yet: the first block is an error
    /// naming it (never a silent LinuxCNC reading).
    Unread {
        /// The dialect.
        dialect: Dialect,
        /// The error was handed on.
        done: bool,
        /// The (empty) block and origin the accessors return.
        block: Block,
        executed: Executed,
    },
}

impl Front {
    /// The front for `choice`, reading `input` named `path`.
    pub(crate) fn new(
        choice: &DialectChoice,
        input: Box<dyn ProgramInput>,
        path: &Path,
        language: LanguageOptions,
        setup: &crate::gcode::ProgramSetup,
    ) -> Front {
        match choice.dialect {
            Dialect::LinuxCnc => Front::LinuxCnc(Executor::new(input, path, language)),
            Dialect::Sinumerik => Front::Sinumerik(Box::new(
                crate::gcode::sinumerik::SinumerikFront::new(input, path, language, setup),
            )),
            dialect @ Dialect::Heidenhain => Front::Unread {
                dialect,
                done: false,
                block: Block::default(),
                executed: Executed {
                    file: 0,
                    line: 1,
                    literal: true,
                    passed: false,
                },
            },
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
            Front::Unread { dialect, done, .. } => {
                if *done {
                    return None;
                }
                *done = true;
                Some(Err(GcodeError::at(
                    ErrorKind::DialectFeature(dialect.name(), "programs".to_string()),
                    1,
                    b"",
                    0,
                    0,
                )))
            }
        }
    }

    /// The last executed block.
    #[inline]
    pub(crate) fn block(&self) -> &Block {
        match self {
            Front::LinuxCnc(e) => e.block(),
            Front::Sinumerik(s) => s.block(),
            Front::Unread { block, .. } => block,
        }
    }

    /// Where the last executed block came from.
    #[inline]
    pub(crate) fn executed(&self) -> &Executed {
        match self {
            Front::LinuxCnc(e) => e.executed(),
            Front::Sinumerik(s) => s.executed(),
            Front::Unread { executed, .. } => executed,
        }
    }

    /// Name of file `index` (0: the main program).
    pub(crate) fn file_name(&self, index: usize) -> &str {
        match self {
            Front::LinuxCnc(e) => e.file_name(index),
            Front::Sinumerik(s) => s.file_name(index),
            Front::Unread { .. } => "?",
        }
    }

    /// The machine-state layer saw the program's end.
    pub(crate) fn end_program(&mut self) {
        match self {
            Front::LinuxCnc(e) => e.end_program(),
            Front::Sinumerik(s) => s.end_program(),
            Front::Unread { done, .. } => *done = true,
        }
    }

    /// After the end: the next line of the main file as written.
    pub(crate) fn next_tail_line(&mut self) -> Option<Result<(), GcodeError>> {
        match self {
            Front::LinuxCnc(e) => e.next_tail_line(),
            Front::Sinumerik(s) => s.next_tail_line(),
            Front::Unread { .. } => None,
        }
    }

    /// The program ended at a closing `%`.
    pub(crate) fn percent_ended(&self) -> bool {
        match self {
            Front::LinuxCnc(e) => e.percent_ended(),
            Front::Sinumerik(s) => s.percent_ended(),
            Front::Unread { .. } => false,
        }
    }

    /// Lines read from the main program so far.
    pub(crate) fn lines_read(&self) -> usize {
        match self {
            Front::LinuxCnc(e) => e.lines_read(),
            Front::Sinumerik(s) => s.lines_read(),
            Front::Unread { .. } => 0,
        }
    }

    /// The product of the counts of the counted loops being run.
    pub(crate) fn repeat_trips(&self) -> f64 {
        match self {
            Front::LinuxCnc(e) => e.repeat_trips(),
            Front::Sinumerik(_) => 1.0,
            Front::Unread { .. } => 1.0,
        }
    }

    /// The innermost loop being run, as messages name it.
    pub(crate) fn innermost_loop(&self) -> Option<String> {
        match self {
            Front::LinuxCnc(e) => e.innermost_loop(),
            Front::Sinumerik(s) => s.innermost_loop(),
            Front::Unread { .. } => None,
        }
    }
}
