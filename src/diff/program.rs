//! Reading a program as a stream of [`BlockSummary`] (a [`Program`] run), and
//! diffing two programs end to end.
use super::align::{AlignOptions, Aligner, BlockSummary};
use super::{DiffAccumulator, DiffReport};
use crate::gcode::{
    Block, BlockEvent, Execution, GcodeError, InterpretOptions, MotionKind, Program,
};
use crate::stamp::PREFIX as STAMP_PREFIX;
use std::cell::RefCell;
use std::rc::Rc;

/// Settings of a diff.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffOptions {
    /// How the blocks of A and B are paired.
    pub align: AlignOptions,
    /// Interpreter settings used for both programs.
    pub interpret: InterpretOptions,
    /// How many of the largest changes (and added/removed lines) the report keeps.
    pub top: usize,
}

impl Default for DiffOptions {
    fn default() -> Self {
        DiffOptions {
            align: AlignOptions::default(),
            interpret: InterpretOptions::default(),
            top: 10,
        }
    }
}

/// Motion kind code of the alignment: 0 = G0, 1 = G1, 2 = G2, 3 = G3.
pub fn motion_code(kind: &MotionKind) -> u8 {
    match kind {
        MotionKind::Rapid => 0,
        MotionKind::Linear => 1,
        MotionKind::Arc {
            clockwise: true, ..
        } => 2,
        MotionKind::Arc { .. } => 3,
    }
}

/// The block's words without N number and comments, upper-cased, whitespace removed.
pub fn block_key(block: &Block) -> String {
    let mut bytes = Vec::with_capacity(block.raw.len());
    let n_span = block.word(b'N').map(|w| w.span());
    for (i, &b) in block.raw.iter().enumerate() {
        if b.is_ascii_whitespace()
            || n_span.as_ref().is_some_and(|s| s.contains(&i))
            || block.comments.iter().any(|c| c.contains(&i))
        {
            continue;
        }
        bytes.push(b.to_ascii_uppercase());
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

/// The summary of one interpreted block.
pub fn summarize(block: &Block, event: &BlockEvent) -> BlockSummary {
    BlockSummary {
        line: block.line,
        number: block
            .block_number()
            .filter(|n| *n >= 0.0 && n.fract() == 0.0 && *n < u64::MAX as f64)
            .map(|n| n as u64),
        // The block's last move: where it leaves the tool (a canned cycle's
        // or a G28's too).
        motion: event
            .motions()
            .last()
            .filter(|_| !event.skipped)
            .map(|m| (motion_code(&m.kind), m.end)),
        key: block_key(block),
        path: event.motions().last().filter(|_| !event.skipped).copied(),
        written_for: written_for(block),
    }
}

/// The original line a writer's comment says the block stands for (see
/// [`BlockSummary::written_for`]).
fn written_for(block: &Block) -> Option<usize> {
    block.comments.iter().find_map(|c| {
        let text = std::str::from_utf8(block.raw.get(c.clone())?).ok()?;
        let inner = text.strip_prefix("(volcomp: ")?;
        let flat = inner.ends_with(" written flat below)")
            || inner.ends_with(" expanded below)")
            || inner.starts_with("G5.2 control point of line ");
        if !flat {
            return None;
        }
        let after = &inner[inner.find("line ")? + 5..];
        let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
        digits.parse().ok()
    })
}

/// Streaming block summaries of a program. Yields `Err` once for the first bad
/// block (located, with the file name) and then ends.
pub struct BlockSummaries {
    run: Execution,
    failed: bool,
    /// A Heidenhain program (its block numbers do not pair blocks).
    klartext: bool,
}

impl BlockSummaries {
    /// The blocks of `program` run with `interpret`.
    pub fn new(program: Program, interpret: InterpretOptions) -> Self {
        let klartext = program.dialect().dialect == crate::gcode::Dialect::Heidenhain;
        BlockSummaries {
            run: program.run(interpret),
            failed: false,
            klartext,
        }
    }
}

impl Iterator for BlockSummaries {
    type Item = Result<BlockSummary, GcodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.failed {
            return None;
        }
        loop {
            match self.run.next()? {
                // The provenance stamp is shown apart (`diff` prints it), not
                // compared as added blocks.
                Ok((block, _, _)) if block.raw.starts_with(STAMP_PREFIX.as_bytes()) => continue,
                // A Klartext stamp block (`3 ; volcomp-stamp …`).
                Ok((block, _, _))
                    if block.raw.first().is_some_and(u8::is_ascii_digit)
                        && crate::stamp::is_stamp_line(&block.raw) =>
                {
                    continue;
                }
                Ok((block, event, _)) => {
                    let mut summary = summarize(block, event);
                    // Klartext block numbers are a sequence the writer
                    // renumbers, not labels: blocks pair by their content.
                    if self.klartext {
                        summary.number = None;
                    }
                    return Some(Ok(summary));
                }
                Err(e) => {
                    self.failed = true;
                    return Some(Err(e));
                }
            }
        }
    }
}

/// Turns a fallible stream into a plain one that stops at the first error and
/// keeps it for later.
struct StopAtError<I> {
    inner: I,
    error: Rc<RefCell<Option<GcodeError>>>,
}

impl<I: Iterator<Item = Result<BlockSummary, GcodeError>>> Iterator for StopAtError<I> {
    type Item = BlockSummary;

    fn next(&mut self) -> Option<BlockSummary> {
        if self.error.borrow().is_some() {
            return None;
        }
        match self.inner.next()? {
            Ok(s) => Some(s),
            Err(e) => {
                *self.error.borrow_mut() = Some(e);
                None
            }
        }
    }
}

/// Diff program `a` against `b` (B − A), streaming both.
pub fn diff_programs(
    a: Program,
    b: Program,
    options: &DiffOptions,
) -> Result<DiffReport, GcodeError> {
    let error_a = Rc::new(RefCell::new(None));
    let error_b = Rc::new(RefCell::new(None));
    let stream_a = StopAtError {
        inner: BlockSummaries::new(a, options.interpret),
        error: Rc::clone(&error_a),
    };
    let stream_b = StopAtError {
        inner: BlockSummaries::new(b, options.interpret),
        error: Rc::clone(&error_b),
    };
    let mut acc = DiffAccumulator::new(options.top);
    for item in Aligner::new(stream_a, stream_b, options.align) {
        if error_a.borrow().is_some() || error_b.borrow().is_some() {
            break;
        }
        acc.push(&item);
    }
    if let Some(e) = error_a.borrow_mut().take() {
        return Err(e);
    }
    if let Some(e) = error_b.borrow_mut().take() {
        return Err(e);
    }
    Ok(acc.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_drops_n_comments_spaces_and_case() {
        let block = crate::gcode::parse_block("N10 g1 X  16.339 (cut) F 159 ; end").unwrap();
        assert_eq!(block_key(&block), "G1X16.339F159");
    }

    #[test]
    fn a_program_diffed_with_itself_is_identical() {
        let text = "G21 G90\nN10 G0 X1 Y2 Z3\nG1 X5 F100 (c)\nG2 X7 Y4 I1 J1\nM2\n";
        let r = diff_programs(
            Program::from_text(text, "p.nc"),
            Program::from_text(text, "p.nc"),
            &DiffOptions::default(),
        )
        .unwrap();
        assert!(r.is_identical());
        assert_eq!(r.unchanged, 5);
        assert_eq!(r.max_xyz_change_um, 0.0);
    }

    #[test]
    fn a_bad_line_is_located_in_its_file() {
        let good = "G1 X1 F100\n";
        let bad = "G1 X1 F100\nG1 X(oops\n";
        let e = diff_programs(
            Program::from_text(good, "a.nc"),
            Program::from_text(bad, "b.nc"),
            &DiffOptions::default(),
        )
        .unwrap_err();
        assert_eq!(e.line, 2);
        assert_eq!(e.path.as_deref(), Some(std::path::Path::new("b.nc")));
    }
}
