//! A program run through both layers: the language layer ([`Executor`]) yields
//! executed blocks, the machine-state layer ([`Interpreter`]) gives each its
//! meaning. This is the one seam every consumer reads programs through.
//!
//! ```
//! use volcomp::gcode::{Execution, InterpretOptions, ProgramSetup};
//! let program = "#1 = 2\nO1 repeat [#1]\n  G91 G1 X1 F100\nO1 endrepeat\nM2\n";
//! let mut run = Execution::new(
//!     Box::new(std::io::Cursor::new(program.as_bytes().to_vec())),
//!     std::path::Path::new("p.ngc"),
//!     InterpretOptions::default(),
//!     &ProgramSetup::default(),
//! );
//! let mut ends = Vec::new();
//! while let Some(step) = run.next() {
//!     let (_, event, _) = step.unwrap();
//!     ends.extend(event.motions().map(|m| m.end.x));
//! }
//! assert_eq!(ends, vec![1.0, 2.0]);
//! ```
use std::path::{Path, PathBuf};

use crate::axes::Axes;
use crate::gcode::dialect::{Dialect, DialectChoice, OrientationSolver};
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::front::Front;
use crate::gcode::language::parameters::{Parameters, numbers};
use crate::gcode::language::{Executed, LanguageOptions, ProgramInput};
use crate::gcode::machine::interpret::{BlockEvent, InterpretOptions, Interpreter};
use crate::gcode::syntax::block::Block;

/// What a real setup holds before the program starts: parameters (work
/// origins, stored positions: a LinuxCNC `.var` file, `--offset`) and where
/// subroutine files are.
#[derive(Clone, Debug, Default)]
pub struct ProgramSetup {
    /// The parameter table the program starts with (work origins, G92
    /// offsets, stored positions, at LinuxCNC's numbers).
    pub parameters: Parameters,
    /// The tool table (`--tools`, the machine file's `[[tools]]`; empty: any
    /// tool may be selected and the default tool is used throughout).
    pub tools: crate::gcode::machine::tools::ToolTable,
    /// Settings of the language layer (subroutine path, loop limits).
    pub language: LanguageOptions,
    /// A program must end with M2, M30 or a closing `%` (LinuxCNC: "File
    /// ended with no percent sign or program end"); off for fragments.
    pub require_program_end: bool,
    /// Where the run's warnings are collected (shared: a clone of the setup
    /// adds to the same collection).
    pub warnings: crate::warnings::Warnings,
    /// The dialect the program is read in (`--dialect`); `None`: detected
    /// from the program's name and first line ([`crate::gcode::detect_dialect`]).
    pub dialect: Option<Dialect>,
    /// Tool axis ↔ rotary joints from the machine's chain, for the blocks of
    /// a dialect that need it (orientation vectors, swivelled planes);
    /// `None`: such a block is a located error.
    pub orientation: Option<std::sync::Arc<dyn OrientationSolver>>,
    /// The SINUMERIK settable frames `G505`–`G599` (`--offset G505=…`), by
    /// their G number: X Y Z and rotary offsets, mm and degrees. `G54`–`G57`
    /// are LinuxCNC's systems 1–4 in [`Self::parameters`].
    pub settable_frames: std::collections::BTreeMap<u16, Axes>,
    /// Values of SINUMERIK system variables the program reads that cannot
    /// be known offline (`--sysvar '$P_UIFR[1,X,TR]=5'`), by their text
    /// upper-cased without spaces, indices included
    /// ([`normalise_system_variable`]).
    pub system_variables: std::collections::BTreeMap<String, f64>,
}

/// The key of a system variable's text in
/// [`ProgramSetup::system_variables`]: upper case, no spaces (`$p_uifr[1, x,
/// tr]` → `$P_UIFR[1,X,TR]`).
pub fn normalise_system_variable(text: &str) -> String {
    text.chars()
        .filter(|c| !c.is_whitespace())
        .map(|c| c.to_ascii_uppercase())
        .collect()
}

/// The dialect of a program: `setup`'s `--dialect`, else detected from its
/// name and the start of `input` (read without being consumed).
pub(crate) fn resolve_dialect(
    setup: &ProgramSetup,
    path: &Path,
    input: &mut dyn ProgramInput,
) -> DialectChoice {
    if let Some(d) = setup.dialect {
        return DialectChoice::given(d);
    }
    let head = input.fill_buf().unwrap_or(&[]);
    crate::gcode::dialect::detect(path, head)
}

impl ProgramSetup {
    /// Set the origin of work coordinate system `n` (1 = G54 … 9 = G59.3;
    /// 505 … 599: the SINUMERIK settable frame `G505` … `G599`), mm and
    /// degrees.
    pub fn set_origin(&mut self, n: usize, origin: &Axes) {
        if let Ok(g @ 505..=599) = u16::try_from(n) {
            self.settable_frames.insert(g, *origin);
            return;
        }
        for (k, v) in origin.to_array().into_iter().enumerate() {
            self.parameters.set(numbers::coord(n, k), v);
        }
    }
}

/// A program to run: where its text comes from, its name in messages, and
/// the setup it runs in. Every command reads programs through this.
pub struct Program {
    input: Box<dyn ProgramInput>,
    path: PathBuf,
    setup: ProgramSetup,
    dialect: DialectChoice,
}

impl Program {
    /// A program read from `input`, named `path` in messages, run with
    /// `setup`.
    pub fn new(mut input: Box<dyn ProgramInput>, path: &Path, setup: ProgramSetup) -> Self {
        let dialect = resolve_dialect(&setup, path, input.as_mut());
        Program {
            input,
            path: path.to_path_buf(),
            setup,
            dialect,
        }
    }

    /// The dialect it is read in, and why.
    pub fn dialect(&self) -> &DialectChoice {
        &self.dialect
    }

    /// A program held in memory (tests, examples), with the default setup
    /// (no offsets, no subroutine path, program end not required).
    pub fn from_text(text: &str, name: &str) -> Self {
        Program::new(
            Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
            Path::new(name),
            ProgramSetup::default(),
        )
    }

    /// A program file, buffered.
    pub fn open(path: &Path, setup: ProgramSetup) -> std::io::Result<Self> {
        let file = std::fs::File::open(path)?;
        Ok(Program::new(
            Box::new(std::io::BufReader::with_capacity(1 << 16, file)),
            path,
            setup,
        ))
    }

    /// Its name in messages.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Where its run's warnings are collected (a shared handle).
    pub fn warnings(&self) -> crate::warnings::Warnings {
        self.setup.warnings.clone()
    }

    /// The setup it runs with.
    pub fn setup(&self) -> &ProgramSetup {
        &self.setup
    }

    /// Start running it.
    pub fn run(self, options: InterpretOptions) -> Execution {
        Execution::with_dialect(self.input, &self.path, options, &self.setup, self.dialect)
    }
}

/// A program being run. Call [`Execution::next`] until it returns `None`.
pub struct Execution {
    executor: Front,
    dialect: DialectChoice,
    interpreter: Interpreter,
    event: BlockEvent,
    path: PathBuf,
    blocks: usize,
    ended: bool,
    require_end: bool,
    lenient: bool,
    done: bool,
    /// The program has ended; the rest of the main file is passed over.
    tail: bool,
    warnings: crate::warnings::Warnings,
    /// Moves no line of the main program spells out (loops, calls, canned
    /// cycles, splines), and their limit.
    generated_moves: u64,
    max_generated_moves: u64,
}

impl Execution {
    /// Run the program read from `input`, named `path` in messages, in the
    /// dialect `setup` gives or, without one, the one detected.
    pub fn new(
        mut input: Box<dyn ProgramInput>,
        path: &Path,
        options: InterpretOptions,
        setup: &ProgramSetup,
    ) -> Self {
        let dialect = resolve_dialect(setup, path, input.as_mut());
        Execution::with_dialect(input, path, options, setup, dialect)
    }

    /// Run the program in the dialect `dialect`.
    fn with_dialect(
        input: Box<dyn ProgramInput>,
        path: &Path,
        options: InterpretOptions,
        setup: &ProgramSetup,
        dialect: DialectChoice,
    ) -> Self {
        let language = LanguageOptions {
            lenient: options.lenient,
            skip_deleted_blocks: options.skip_deleted_blocks,
            ..setup.language.clone()
        };
        Execution {
            executor: Front::new(&dialect, input, path, language, &options, setup),
            dialect,
            interpreter: {
                let mut i = Interpreter::with_parameters(options, setup.parameters.clone());
                i.set_tools(setup.tools.clone());
                i
            },
            event: BlockEvent::default(),
            path: path.to_path_buf(),
            blocks: 0,
            ended: false,
            require_end: setup.require_program_end,
            lenient: options.lenient,
            done: false,
            tail: false,
            warnings: setup.warnings.clone(),
            generated_moves: 0,
            max_generated_moves: setup
                .language
                .max_generated_moves
                .unwrap_or(crate::gcode::language::DEFAULT_MAX_GENERATED_MOVES),
        }
    }

    /// Count the moves of the block just interpreted that no line of the main
    /// program spells out; an error past the limit, or when a block that
    /// expands (a canned cycle, a spline) inside `repeat` loops would pass
    /// it on its own (its moves × the loops' counts).
    fn count_generated_moves(&mut self) -> Result<(), GcodeError> {
        let executed = self.executor.executed();
        let own = usize::from(executed.literal && self.event.motion().is_some());
        let generated = self.event.motions().count().saturating_sub(own);
        if generated == 0 {
            return Ok(());
        }
        let limit = self.max_generated_moves;
        let expanded = self.event.expanded().len();
        let trips = self.executor.repeat_trips();
        self.generated_moves += generated as u64;
        let kind = if expanded > 0 && trips > 1.0 && expanded as f64 * trips > limit as f64 {
            ErrorKind::MovesEstimate {
                estimate: expanded as f64 * trips,
                per_block: expanded,
                trips,
                limit,
                option: "--max-moves",
                within: self.executor.innermost_loop().unwrap_or_default(),
            }
        } else if self.generated_moves > limit {
            ErrorKind::LoopLimit {
                limit,
                what: "generated moves (loops, calls, canned cycles, splines)",
                option: "--max-moves",
                within: self.executor.innermost_loop().unwrap_or_default(),
            }
        } else {
            return Ok(());
        };
        let executed = self.executor.executed();
        let raw = &self.executor.block().raw;
        // The source line, without the `(volcomp: line N)` of a flat block.
        let raw = match raw.windows(10).rposition(|w| w == b" (volcomp:") {
            Some(k) if !executed.literal => &raw[..k],
            _ => &raw[..],
        };
        let e = GcodeError::at(kind, executed.line, raw, 0, raw.len());
        Err(if executed.file == 0 {
            e.with_path(&self.path)
        } else {
            e.with_path(self.executor.file_name(executed.file))
        })
    }

    /// Add the event's warnings to the run's collection.
    fn collect_warnings(&self) {
        if self.event.warnings.is_empty() {
            return;
        }
        let executed = self.executor.executed();
        let file = if executed.file == 0 {
            self.path.display().to_string()
        } else {
            self.executor.file_name(executed.file).to_string()
        };
        for w in &self.event.warnings {
            self.warnings.add(
                &crate::warnings::Warning {
                    kind: w.kind.key(),
                    file: Some(&file),
                    line: Some(w.line),
                    column: Some(w.column),
                    effect: w.kind.effect(),
                },
                1,
                || w.message(),
            );
        }
    }

    /// The program's name in messages.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The dialect the program is read in, and why.
    pub fn dialect(&self) -> &DialectChoice {
        &self.dialect
    }

    /// The interpreter (its position, origin, parameters).
    pub fn interpreter(&self) -> &Interpreter {
        &self.interpreter
    }

    /// Name of file `index` of [`Executed::file`].
    pub fn file_name(&self, index: usize) -> &str {
        self.executor.file_name(index)
    }

    /// The next executed block with its meaning and its origin in the source.
    /// The lines of a subroutine definition that the main program passes over
    /// come as written, not executed (`skipped` events, [`Executed::passed`]),
    /// unless [`LanguageOptions::drop_definitions`]. After the program's end
    /// (M2, M30, closing `%`) the rest of the main file follows as written,
    /// not executed (`skipped` events), so writers lose no byte.
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Option<Result<(&Block, &BlockEvent, &Executed), GcodeError>> {
        if self.done {
            return None;
        }
        if self.tail {
            return match self.executor.next_tail_line() {
                None => {
                    self.done = true;
                    None
                }
                Some(Err(e)) => {
                    self.done = true;
                    Some(Err(e.with_path(&self.path)))
                }
                Some(Ok(())) => {
                    self.executor.pass_over(&self.interpreter, &mut self.event);
                    let block = self.executor.block();
                    self.event.index = self.blocks;
                    self.blocks += 1;
                    Some(Ok((block, &self.event, self.executor.executed())))
                }
            };
        }
        if self.event.program_end {
            self.ended = true;
            self.executor.end_program();
        }
        match self.executor.next_block(&mut self.interpreter) {
            None if self.ended || self.executor.percent_ended() => {
                self.tail = true;
                self.next()
            }
            None => {
                self.done = true;
                if self.require_end
                    && !self.ended
                    && !self.lenient
                    && !self.executor.percent_ended()
                {
                    let line = self.executor.lines_read();
                    return Some(Err(GcodeError::at(
                        ErrorKind::NoProgramEnd,
                        line.max(1),
                        b"",
                        0,
                        0,
                    )
                    .with_path(&self.path)));
                }
                None
            }
            Some(Err(e)) => {
                self.done = true;
                Some(Err(if e.path.is_none() {
                    e.with_path(&self.path)
                } else {
                    e
                }))
            }
            Some(Ok(())) if self.executor.executed().passed => {
                // A subroutine definition passed over: as written, not run.
                self.executor.pass_over(&self.interpreter, &mut self.event);
                let block = self.executor.block();
                self.event.index = self.blocks;
                self.blocks += 1;
                Some(Ok((block, &self.event, self.executor.executed())))
            }
            Some(Ok(())) => {
                let result = self
                    .executor
                    .interpret(&mut self.interpreter, &mut self.event);
                if let Err(e) = result {
                    self.done = true;
                    let executed = self.executor.executed();
                    let e = if executed.file == 0 {
                        e.with_path(&self.path)
                    } else {
                        e.with_path(self.executor.file_name(executed.file))
                    };
                    // A flattened block's error is about its source line.
                    let e = GcodeError {
                        line: executed.line,
                        ..e
                    };
                    return Some(Err(e));
                }
                if let Err(e) = self.count_generated_moves() {
                    self.done = true;
                    return Some(Err(e));
                }
                self.event.index = self.blocks;
                self.blocks += 1;
                self.collect_warnings();
                Some(Ok((
                    self.executor.block(),
                    &self.event,
                    self.executor.executed(),
                )))
            }
        }
    }
}
