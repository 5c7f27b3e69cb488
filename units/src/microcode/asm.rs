//! The microcode assembly language: a text form of a [`Program`] that a person can write and
//! read. [`assemble`] turns text into a checked program (errors carry `line:column`);
//! [`disassemble`] prints a program so that `assemble(disassemble(p)) == p` for every
//! program that passes [`Program::check`].
//!
//! # Example
//!
//! ```text
//! ; saxpy: z = 2.5*x + y, software-pipelined: one iteration every 2 cycles, 5 stages
//! kernel saxpy
//! in x
//! in y
//! out z
//!
//!     imm 2.5 -> mul0.a[0]                                ; the constant a
//! loop stream x, stages 5:
//!     sin0 x -> mul0.b[0] | mul0 fmul a[0], b[0] -> add0.a[0] @2
//!     sin1 y -> add0.b[0] @2 | add0 fadd a[0], b[0] -> stream z @4
//! end
//! done
//! ```
//!
//! # Lines
//!
//! One statement per line; `;` starts a comment that runs to the end of the line; blank
//! lines and indentation are ignored. Words are case-sensitive.
//!
//! | line | meaning |
//! |---|---|
//! | `kernel NAME` | first line: the kernel's name |
//! | `in NAME`, `out NAME` | declare the next kernel stream (index 0, 1, … in order), before any instruction |
//! | `SLOT \| SLOT \| …` | one VLIW instruction: its non-empty slots, in any order, each at most once |
//! | `nop` | an instruction with every slot empty |
//! | `loop count N[, stages S]:` | the next instruction begins a loop of `N` iterations |
//! | `loop stream NAME[, stages S]:` | … a loop that runs until input stream `NAME` is exhausted |
//! | `loop until cc[K]:` | … a loop that runs until condition code `K` is set in every cluster |
//! | `end` | the previous instruction ends the innermost loop (it may be the loop's only one) |
//! | `pass` | the previous instruction ends a pass of the innermost loop, not its body (see below) |
//! | `done` | the kernel ends: the previous instruction, or an empty one after an `end`, is its last; nothing follows |
//!
//! An instruction line that ends in `|` continues on the next line. `stages S` is the
//! software-pipeline depth (default 1). Names (kernel, streams) are identifiers: a letter or
//! `_`, then letters, digits, `_` or `.`; the grammar is positional, so a stream may be
//! called `in`, `cc` or `stream`.
//!
//! A loop body may be a single instruction: `loop …:`, one instruction line, `end` gives one
//! instruction that both begins and ends the loop (a software-pipelined loop with an
//! initiation interval of 1). An instruction begins at most one loop and ends at most one, so
//! where two `loop` lines (or two `end` lines) would meet, a `nop` separates them. The
//! kernel's last instruction carries only `done`: it is outside every loop and neither begins
//! nor ends one. So `done` after a plain instruction (one that neither begins nor ends a
//! loop) marks that instruction; `done` after an `end` (or with no instruction before it)
//! adds an empty instruction to carry it. Writing `nop` before that `done` gives the same
//! program, and [`disassemble`] prints the short form.
//!
//! A loop body unrolled for modulo variable expansion (Lam 1988) holds several passes, and
//! a `pass` line inside it marks where each but the last ends, as `end` marks the last.
//! Here `z = x + 1.0` starts an iteration every cycle; each `x` lands 3 cycles after its
//! read and is added a cycle later, as the next iteration's lands, so two copies of the
//! kernel alternate between two entries of `add0.a`:
//!
//! ```text
//!     imm 1.0 -> add0.b[0]
//! loop stream x, stages 5:
//!     sin0 x -> add0.a[0] | add0 fadd a[0], b[0] -> stream z @4
//! pass
//!     sin0 x -> add0.a[1] | add0 fadd a[1], b[0] -> stream z @4
//! end
//! ```
//!
//! A pass has at least one instruction (the loop's first may be the whole of the first
//! pass); `pass` right after `loop` or another `pass`, or right before `end` (the last pass
//! would be empty), is an error, and so is `pass` after an `end` of an inner loop (a `nop`
//! separates them, as for two `end`s).
//!
//! # Slots
//!
//! Each slot names its unit, then its operands, then optionally `-> DEST[, DEST]` (up to two
//! destinations) and `@S` (its software-pipeline stage, default 0). Operands name entries of
//! the slot's own LRFs: `a[i]` is entry `i` of `add0.a` in slot `add0`.
//!
//! | slot | syntax |
//! |---|---|
//! | `addN`, `mulN`, `dsqN` | `add0 fadd a[i], b[j]`, one-operand ops `add0 fabs a[i]`, `add0 select cc[k], a[i], b[j]` |
//! | `spN` | read `sp0 ld BASE[, addr[i]] -> …`, write `sp0 st BASE[, addr[i]], data[j]` (address `BASE + sp0.addr[i]`) |
//! | `commN` | `comm0 data[i], PERM -> …`, `PERM` = `rotate K` (from cluster `c + K`), `xor K` (from `c xor K`), `bcast K` (from cluster `K`), `perm[i]` (from the cluster in `comm0.perm[i]`) |
//! | `sinN` | `sin0 NAME -> …`, conditional `sin0 NAME if cc[k] -> …` |
//! | `sout` | `sout NAME, data[i]`, conditional `sout NAME, data[i] if cc[k]` |
//! | `imm` | `imm VALUE -> …`, `VALUE` a decimal integer (negative: two's complement), `0x` hex, a float with `.` or an exponent (`2.5`, `1e-3`: fp32, correctly rounded), or `cid` (the cluster's index) |
//!
//! A destination is an LRF entry `add1.b[3]` (any LRF of the cluster, by its
//! [`lrf_names`](crate::desc::MachineDesc::lrf_names) name), a condition code `cc[2]` (bit 0
//! of the result), or an output stream `stream NAME`. Op mnemonics are [`Op::name`]s.
//! Numbers in other places are decimal or `0x` hex.
//!
//! # Grammar
//!
//! ```text
//! program  = "kernel" NAME NL { ("in" | "out") NAME NL } { body NL }
//! body     = instr | "nop" | "end" | "pass" | "done"
//!          | "loop" ("count" INT | "stream" NAME | "until" "cc" "[" INT "]") ["," "stages" INT] ":"
//! instr    = slot { "|" [NL] slot }
//! slot     = FU OP operands [dests] [stage]            ; FU = addN | mulN | dsqN
//!          | SP "ld" INT ["," "addr" "[" INT "]"] [dests] [stage]
//!          | SP "st" INT ["," "addr" "[" INT "]"] "," "data" "[" INT "]" [stage]
//!          | COMM "data" "[" INT "]" "," perm [dests] [stage]
//!          | SIN NAME [cond] [dests] [stage]
//!          | "sout" NAME "," "data" "[" INT "]" [cond] [stage]
//!          | "imm" (NUMBER | "cid") [dests] [stage]
//! operands = "a" "[" INT "]"                                    ; one-operand ops
//!          | "a" "[" INT "]" "," "b" "[" INT "]"                ; two-operand ops
//!          | "cc" "[" INT "]" "," "a" "[" INT "]" "," "b" "[" INT "]"   ; select
//! perm     = ("rotate" | "xor" | "bcast") INT | "perm" "[" INT "]"
//! cond     = "if" "cc" "[" INT "]"
//! dests    = "->" dest ["," dest]
//! dest     = LRF "[" INT "]" | "cc" "[" INT "]" | "stream" NAME
//! stage    = "@" INT
//! ```
//!
//! # Disassembly
//!
//! [`disassemble`] prints one instruction per line in slot order (`add…`, `mul…`, `dsq…`,
//! `sp…`, `comm…`, `sin…`, `sout`, `imm`), loop bodies indented (`pass` and `end` level
//! with their `loop`), stages only when not 0, and immediates in hex with their value as an
//! integer or fp32 in a trailing comment.

use std::fmt::{self, Write as _};

use crate::desc::MachineDesc;
use crate::ops::Op;

use super::check::{MicrocodeError, Shape, parse_index};
use super::{
    CommSlot, Control, Dest, Dests, FuSlot, ImmValue, Immediate, Instruction, LoopBegin, LoopKind,
    Permutation, Program, SpSlot, StreamDecl, StreamDir, StreamIn, StreamOut,
};

/// An assembly error at `line:col` (both 1-based; `col` counts characters).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AsmError {
    pub line: usize,
    pub col: usize,
    pub message: String,
    /// The check failure, when the text parsed but the program does not fit the machine.
    pub check: Option<Box<MicrocodeError>>,
}

impl fmt::Display for AsmError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.line, self.col, self.message)
    }
}

impl std::error::Error for AsmError {}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Pos {
    line: usize,
    col: usize,
}

fn error(pos: Pos, message: impl Into<String>) -> AsmError {
    AsmError {
        line: pos.line,
        col: pos.col,
        message: message.into(),
        check: None,
    }
}

// ---- lexer ----------------------------------------------------------------------------

#[derive(Clone, Debug, PartialEq, Eq)]
enum Tok {
    Ident(String),
    Num(String),
    Comma,
    Bar,
    LBrack,
    RBrack,
    Colon,
    At,
    Arrow,
}

impl fmt::Display for Tok {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Tok::Ident(s) | Tok::Num(s) => write!(f, "`{s}`"),
            Tok::Comma => f.write_str("`,`"),
            Tok::Bar => f.write_str("`|`"),
            Tok::LBrack => f.write_str("`[`"),
            Tok::RBrack => f.write_str("`]`"),
            Tok::Colon => f.write_str("`:`"),
            Tok::At => f.write_str("`@`"),
            Tok::Arrow => f.write_str("`->`"),
        }
    }
}

#[derive(Clone, Debug)]
struct Token {
    tok: Tok,
    pos: Pos,
}

/// A line's tokens and the position just past its last character (for "expected … at end
/// of line").
struct Line {
    tokens: Vec<Token>,
    end: Pos,
}

fn lex_line(text: &str, line: usize) -> Result<Line, AsmError> {
    let chars: Vec<char> = text.chars().collect();
    let mut tokens = Vec::new();
    let mut i = 0;
    let pos = |i: usize| Pos { line, col: i + 1 };
    let mut end = chars.len();
    while i < chars.len() {
        let c = chars[i];
        let start = i;
        let tok = match c {
            ';' => {
                end = i;
                break;
            }
            c if c.is_whitespace() => {
                i += 1;
                continue;
            }
            ',' => Tok::Comma,
            '|' => Tok::Bar,
            '[' => Tok::LBrack,
            ']' => Tok::RBrack,
            ':' => Tok::Colon,
            '@' => Tok::At,
            '-' if chars.get(i + 1) == Some(&'>') => {
                i += 1;
                Tok::Arrow
            }
            c if c.is_ascii_digit()
                || (c == '-' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit())) =>
            {
                i += 1;
                let hex = chars[start..].starts_with(&['0', 'x'])
                    || chars[start..].starts_with(&['0', 'X']);
                while let Some(&d) = chars.get(i) {
                    let exponent_sign =
                        (d == '-' || d == '+') && !hex && matches!(chars[i - 1], 'e' | 'E');
                    if d.is_ascii_alphanumeric() || d == '.' || d == '_' || exponent_sign {
                        i += 1;
                    } else {
                        break;
                    }
                }
                tokens.push(Token {
                    tok: Tok::Num(chars[start..i].iter().collect()),
                    pos: pos(start),
                });
                continue;
            }
            c if c.is_ascii_alphabetic() || c == '_' => {
                while chars
                    .get(i)
                    .is_some_and(|d| d.is_ascii_alphanumeric() || *d == '_' || *d == '.')
                {
                    i += 1;
                }
                tokens.push(Token {
                    tok: Tok::Ident(chars[start..i].iter().collect()),
                    pos: pos(start),
                });
                continue;
            }
            c => return Err(error(pos(i), format!("unexpected character `{c}`"))),
        };
        i += 1;
        tokens.push(Token {
            tok,
            pos: pos(start),
        });
    }
    // The end position is just past the last non-blank character before any comment.
    while end > 0 && chars[end - 1].is_whitespace() {
        end -= 1;
    }
    Ok(Line {
        tokens,
        end: pos(end),
    })
}

// ---- token cursor ---------------------------------------------------------------------

struct Cursor<'t> {
    toks: &'t [Token],
    i: usize,
    end: Pos,
}

impl<'t> Cursor<'t> {
    fn peek(&self) -> Option<&'t Token> {
        self.toks.get(self.i)
    }

    fn peek_tok(&self) -> Option<&'t Tok> {
        self.peek().map(|t| &t.tok)
    }

    fn at_end(&self) -> bool {
        self.i >= self.toks.len()
    }

    /// Position of the next token, or the end of the line.
    fn pos(&self) -> Pos {
        self.peek().map_or(self.end, |t| t.pos)
    }

    fn unexpected(&self, wanted: &str) -> AsmError {
        match self.peek() {
            Some(t) => error(t.pos, format!("expected {wanted}, found {}", t.tok)),
            None => error(
                self.end,
                format!("expected {wanted} at the end of the line"),
            ),
        }
    }

    fn eat(&mut self, tok: &Tok) -> bool {
        if self.peek_tok() == Some(tok) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn expect(&mut self, tok: Tok) -> Result<Pos, AsmError> {
        let pos = self.pos();
        if self.eat(&tok) {
            Ok(pos)
        } else {
            Err(self.unexpected(&tok.to_string()))
        }
    }

    fn eat_word(&mut self, word: &str) -> bool {
        if matches!(self.peek_tok(), Some(Tok::Ident(w)) if w == word) {
            self.i += 1;
            true
        } else {
            false
        }
    }

    fn expect_word(&mut self, word: &str) -> Result<Pos, AsmError> {
        let pos = self.pos();
        if self.eat_word(word) {
            Ok(pos)
        } else {
            Err(self.unexpected(&format!("`{word}`")))
        }
    }

    fn ident(&mut self, what: &str) -> Result<(String, Pos), AsmError> {
        match self.peek() {
            Some(Token {
                tok: Tok::Ident(s),
                pos,
            }) => {
                self.i += 1;
                Ok((s.clone(), *pos))
            }
            _ => Err(self.unexpected(what)),
        }
    }

    /// A non-negative integer (decimal or `0x` hex) of at most `max`.
    fn uint(&mut self, what: &str, max: u64) -> Result<(u64, Pos), AsmError> {
        let Some(Token {
            tok: Tok::Num(s),
            pos,
        }) = self.peek()
        else {
            return Err(self.unexpected(what));
        };
        self.i += 1;
        let v = parse_uint(s).ok_or_else(|| {
            error(
                *pos,
                format!("`{s}` is not a non-negative integer (decimal or 0x hex)"),
            )
        })?;
        if v > max {
            return Err(error(
                *pos,
                format!("{what} {v} is too large (at most {max})"),
            ));
        }
        Ok((v, *pos))
    }

    fn u16(&mut self, what: &str) -> Result<u16, AsmError> {
        Ok(self.uint(what, u64::from(u16::MAX))?.0 as u16)
    }

    /// `word[N]`, returning `N` and the position of `word`.
    fn indexed(&mut self, word: &str) -> Result<(u16, Pos), AsmError> {
        let pos = self.expect_word(word)?;
        self.expect(Tok::LBrack)?;
        let v = self.u16(&format!("an entry of `{word}`"))?;
        self.expect(Tok::RBrack)?;
        Ok((v, pos))
    }
}

fn parse_uint(s: &str) -> Option<u64> {
    if let Some(h) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        if h.is_empty() || h.len() > 16 {
            return None;
        }
        return u64::from_str_radix(h, 16).ok();
    }
    if !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// A 32-bit word written as text, as an immediate or an input stream's value: decimal
/// (two's complement if negative), hex, or an fp32 float (with '.' or an exponent). A float
/// beyond fp32's range, or a nonzero one that rounds to zero, is an error rather than an
/// infinity or a zero nobody wrote; infinities and NaNs are written in hex.
pub fn parse_word(s: &str) -> Result<u32, String> {
    let (neg, body) = match s.strip_prefix('-') {
        Some(b) => (true, b),
        None => (false, s),
    };
    if let Some(h) = body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
        if neg {
            return Err(format!("`{s}`: a hex immediate is written without a sign"));
        }
        if h.is_empty() || h.len() > 8 || !h.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(format!(
                "`{s}` is not a 32-bit hex number (up to 8 hex digits)"
            ));
        }
        return Ok(u32::from_str_radix(h, 16).expect("checked hex digits"));
    }
    if ["inf", "infinity", "nan"].contains(&body.to_ascii_lowercase().as_str()) {
        return Err(format!(
            "`{s}`: write infinities and NaNs in hex (0x7f800000 is +inf, 0x7fc00000 a NaN)"
        ));
    }
    if body.contains(['.', 'e', 'E']) {
        return parse_fp32(s, body);
    }
    if !body.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("`{s}` is not a number"));
    }
    let v: i64 = s
        .parse()
        .map_err(|_| format!("`{s}` does not fit 32 bits"))?;
    if !(-(1i64 << 31)..(1i64 << 32)).contains(&v) {
        return Err(format!(
            "`{s}` does not fit 32 bits (-2147483648..=4294967295)"
        ));
    }
    Ok(v as u32)
}

/// [`parse_word`] for fp32 values (`imagine kernel run --format f32`): a decimal integer is
/// the float it names (`10` is 10.0, `0x41200000`), not a bit pattern; hex stays a bit
/// pattern, and floats are read as [`parse_word`] reads them, with the same range errors.
pub fn parse_f32_word(s: &str) -> Result<u32, String> {
    let body = s.strip_prefix('-').unwrap_or(s);
    if !body.is_empty() && body.bytes().all(|b| b.is_ascii_digit()) {
        return parse_fp32(s, body);
    }
    parse_word(s)
}

/// `s` (unsigned part `body`) as fp32 bits: an error beyond fp32's range, or for a nonzero
/// value that rounds to zero.
fn parse_fp32(s: &str, body: &str) -> Result<u32, String> {
    let ok = body
        .bytes()
        .all(|b| b.is_ascii_digit() || matches!(b, b'.' | b'e' | b'E' | b'+' | b'-'));
    let mantissa = body.split(['e', 'E']).next().unwrap_or("");
    let nonzero = mantissa.bytes().any(|b| (b'1'..=b'9').contains(&b));
    match s.parse::<f32>() {
        Ok(f) if ok && f == 0.0 && nonzero => Err(format!(
            "`{s}` is below the range of fp32 (it rounds to zero)"
        )),
        Ok(f) if ok && f.is_finite() => Ok(f.to_bits()),
        Ok(_) if ok => Err(format!("`{s}` is beyond the range of fp32")),
        _ => Err(format!("`{s}` is not a number")),
    }
}

// ---- assembler ------------------------------------------------------------------------

/// Where each part of an instruction was written, to place check errors.
struct Where {
    line: Pos,
    /// `(field or slot name, position)`: `add0`, `add0.a`, `add0.dest1`, `ctl`.
    parts: Vec<(String, Pos)>,
}

impl Where {
    fn find(&self, field: &str) -> Pos {
        let mut name = field;
        loop {
            if let Some((_, p)) = self.parts.iter().find(|(n, _)| n == name) {
                return *p;
            }
            match name.rfind('.') {
                Some(dot) => name = &name[..dot],
                None => return self.line,
            }
        }
    }
}

/// A `loop` whose `end` has not been read yet.
struct OpenLoop {
    /// Index of its first instruction.
    begin: usize,
    /// Where its `loop` line is.
    line: Pos,
    /// Index of the first instruction of its current pass.
    pass_begin: usize,
    /// Its last `pass` line so far.
    pass: Option<Pos>,
}

struct Assembler<'d> {
    desc: &'d MachineDesc,
    shape: Shape,
    streams: Vec<StreamDecl>,
}

/// Assembles `text` into a program for `desc` and [checks](Program::check) it.
pub fn assemble(text: &str, desc: &MachineDesc) -> Result<Program, AsmError> {
    let asm = Assembler {
        desc,
        shape: Shape::new(desc),
        streams: Vec::new(),
    };
    asm.run(text)
}

impl Assembler<'_> {
    fn run(mut self, text: &str) -> Result<Program, AsmError> {
        // Lex, joining lines that end in `|` with the next.
        let mut lines: Vec<Line> = Vec::new();
        let mut continuing = false;
        let mut last_end = Pos { line: 1, col: 1 };
        for (n, src) in text.lines().enumerate() {
            let line = lex_line(src, n + 1)?;
            last_end = Pos {
                line: n + 1,
                col: line.end.col,
            };
            if line.tokens.is_empty() {
                continue;
            }
            let ends_with_bar = line.tokens.last().map(|t| &t.tok) == Some(&Tok::Bar);
            if continuing {
                let prev = lines.last_mut().expect("a continued line exists");
                prev.tokens.extend(line.tokens);
                prev.end = line.end;
            } else {
                lines.push(line);
            }
            continuing = ends_with_bar;
        }
        if continuing {
            return Err(error(
                last_end,
                "the last instruction ends in `|` but no slot follows",
            ));
        }

        let mut lines = lines.into_iter();
        let Some(first) = lines.next() else {
            return Err(error(
                last_end,
                "empty program: it starts with `kernel NAME`",
            ));
        };
        let mut c = Cursor {
            toks: &first.tokens,
            i: 0,
            end: first.end,
        };
        let kernel_pos = c.expect_word("kernel").map_err(|mut e| {
            e.message = format!("{}: a program starts with `kernel NAME`", e.message);
            e
        })?;
        let (name, _) = c.ident("the kernel's name")?;
        end_of_line(&c)?;

        let mut code: Vec<Instruction> = Vec::new();
        let mut wheres: Vec<Where> = Vec::new();
        let mut pending: Option<(LoopBegin, Pos)> = None;
        let mut open: Vec<OpenLoop> = Vec::new();
        let mut done: Option<Pos> = None;
        for line in lines {
            let mut c = Cursor {
                toks: &line.tokens,
                i: 0,
                end: line.end,
            };
            let start = c.pos();
            let word = match c.peek_tok() {
                Some(Tok::Ident(w)) => w.as_str(),
                _ => "",
            };
            if let Some(d) = done {
                return Err(error(
                    start,
                    format!(
                        "nothing may follow `done` (line {}); the kernel ends there",
                        d.line
                    ),
                ));
            }
            match word {
                "kernel" => {
                    return Err(error(start, "one program per text: a second `kernel`"));
                }
                "in" | "out" => {
                    c.i += 1;
                    if !code.is_empty() || pending.is_some() {
                        return Err(error(
                            start,
                            "streams are declared before the first instruction",
                        ));
                    }
                    self.declare(&mut c, word == "in")?;
                }
                "loop" => {
                    c.i += 1;
                    if let Some((_, p)) = pending {
                        return Err(error(
                            start,
                            format!(
                                "two loops cannot begin on the same instruction (the loop at \
                                 line {} has no instruction yet); put an instruction, a `nop` \
                                 if need be, between them",
                                p.line
                            ),
                        ));
                    }
                    let begin = self.loop_header(&mut c)?;
                    open.push(OpenLoop {
                        begin: code.len(),
                        line: start,
                        pass_begin: code.len(),
                        pass: None,
                    });
                    pending = Some((begin, start));
                }
                "end" => {
                    c.i += 1;
                    end_of_line(&c)?;
                    let Some(OpenLoop {
                        begin,
                        line: loop_pos,
                        pass_begin,
                        pass,
                    }) = open.pop()
                    else {
                        return Err(error(start, "`end` without an open `loop`"));
                    };
                    if pending.is_some() {
                        return Err(error(
                            start,
                            format!(
                                "the loop at line {} has an empty body; a loop body has at \
                                 least one instruction",
                                loop_pos.line
                            ),
                        ));
                    }
                    if let (Some(p), true) = (pass, pass_begin == code.len()) {
                        return Err(error(
                            start,
                            format!(
                                "`end` right after the `pass` at line {}: the loop's last pass \
                                 would be empty, and one instruction would end both a pass and \
                                 the loop; drop that `pass` (`end` ends the last pass)",
                                p.line
                            ),
                        ));
                    }
                    // The loop's first instruction exists (`pending` was taken), so `last`
                    // is `begin` (a one-instruction body) or after it.
                    let last = code.len() - 1;
                    debug_assert!(last >= begin);
                    if code[last].control.end {
                        return Err(error(
                            start,
                            "two loops cannot end on the same instruction; put an \
                             instruction, a `nop` if need be, before this `end`",
                        ));
                    }
                    code[last].control.end = true;
                    wheres[last].parts.push(("ctl.end".into(), start));
                }
                "pass" => {
                    c.i += 1;
                    end_of_line(&c)?;
                    let Some(l) = open.last_mut() else {
                        return Err(error(
                            start,
                            "`pass` outside a loop; it ends a pass of the innermost loop's \
                             body",
                        ));
                    };
                    if pending.is_some() {
                        return Err(error(
                            start,
                            format!(
                                "`pass` right after the `loop` at line {}: the pass has no \
                                 instruction; a pass holds at least one",
                                l.line.line
                            ),
                        ));
                    }
                    if let (Some(p), true) = (l.pass, l.pass_begin == code.len()) {
                        return Err(error(
                            start,
                            format!(
                                "no instruction since the `pass` at line {}: a pass holds at \
                                 least one instruction",
                                p.line
                            ),
                        ));
                    }
                    // The pass's last instruction exists and is in this loop (its first
                    // instruction exists: `pending` was taken).
                    let last = code.len() - 1;
                    if code[last].control.end {
                        return Err(error(
                            start,
                            "the previous instruction ends an inner loop, so it cannot end a \
                             pass of this one too; put an instruction, a `nop` if need be, \
                             before this `pass`",
                        ));
                    }
                    code[last].control.pass_end = true;
                    wheres[last].parts.push(("ctl.pass".into(), start));
                    l.pass_begin = code.len();
                    l.pass = Some(start);
                }
                "done" => {
                    c.i += 1;
                    end_of_line(&c)?;
                    if let Some(OpenLoop { line: p, .. }) = open.last() {
                        return Err(error(
                            start,
                            format!(
                                "`done` inside the loop at line {}; close it with `end` first",
                                p.line
                            ),
                        ));
                    }
                    match code.last_mut() {
                        Some(ins) if ins.control.is_next() => {
                            ins.control.done = true;
                            wheres
                                .last_mut()
                                .expect("one per instruction")
                                .parts
                                .push(("ctl.done".into(), start));
                        }
                        _ => {
                            let mut ins = self.empty();
                            ins.control = Control::DONE;
                            code.push(ins);
                            wheres.push(Where {
                                line: start,
                                parts: vec![("ctl.done".into(), start)],
                            });
                        }
                    }
                    done = Some(start);
                }
                _ => {
                    let (mut ins, mut w) = if word == "nop" {
                        c.i += 1;
                        end_of_line(&c)?;
                        (
                            self.empty(),
                            Where {
                                line: start,
                                parts: Vec::new(),
                            },
                        )
                    } else {
                        self.instruction(&mut c)?
                    };
                    if let Some((begin, p)) = pending.take() {
                        ins.control.begin = Some(begin);
                        w.parts.push(("ctl".into(), p));
                    }
                    code.push(ins);
                    wheres.push(w);
                }
            }
        }
        if let Some(OpenLoop { line: p, .. }) = open.last() {
            return Err(error(*p, "this loop is never closed with `end`"));
        }
        if done.is_none() {
            return Err(error(last_end, "the kernel does not end with `done`"));
        }
        let program = Program {
            name,
            streams: self.streams,
            code,
        };
        if let Err(e) = program.check(self.desc) {
            let pos = match e.instruction {
                Some(i) => match &e.field {
                    Some(f) => wheres[i].find(f),
                    None => wheres[i].line,
                },
                None => kernel_pos,
            };
            return Err(AsmError {
                line: pos.line,
                col: pos.col,
                message: e.to_string(),
                check: Some(Box::new(e)),
            });
        }
        Ok(program)
    }

    fn empty(&self) -> Instruction {
        Instruction::empty(self.desc)
    }

    fn declare(&mut self, c: &mut Cursor<'_>, input: bool) -> Result<(), AsmError> {
        let (name, pos) = c.ident("a stream name")?;
        end_of_line(c)?;
        if self.streams.iter().any(|s| s.name == name) {
            return Err(error(pos, format!("stream `{name}` is already declared")));
        }
        let max = self.desc.srf.kernel_streams;
        if self.streams.len() >= max {
            return Err(error(
                pos,
                format!(
                    "a kernel may address at most {max} streams (`srf.kernel_streams`); \
                     `{name}` would be stream {}",
                    self.streams.len()
                ),
            ));
        }
        self.streams.push(StreamDecl {
            name,
            dir: if input { StreamDir::In } else { StreamDir::Out },
        });
        Ok(())
    }

    fn stream(&self, name: &str, pos: Pos) -> Result<u16, AsmError> {
        self.streams
            .iter()
            .position(|s| s.name == name)
            .map(|i| i as u16)
            .ok_or_else(|| {
                let names: Vec<&str> = self.streams.iter().map(|s| s.name.as_str()).collect();
                error(
                    pos,
                    format!(
                        "no stream `{name}` is declared (declared: {})",
                        if names.is_empty() {
                            "none".to_string()
                        } else {
                            names.join(", ")
                        }
                    ),
                )
            })
    }

    /// After `loop`: `count N | stream NAME | until cc[K]` `[, stages S]` `:`.
    fn loop_header(&self, c: &mut Cursor<'_>) -> Result<LoopBegin, AsmError> {
        let kind = if c.eat_word("count") {
            LoopKind::Counted(c.uint("an iteration count", u64::from(u32::MAX))?.0 as u32)
        } else if c.eat_word("stream") {
            let (name, pos) = c.ident("an input stream's name")?;
            LoopKind::UntilStreamEmpty(self.stream(&name, pos)?)
        } else if c.eat_word("until") {
            LoopKind::UntilCc(c.indexed("cc")?.0)
        } else {
            return Err(c.unexpected("`count N`, `stream NAME` or `until cc[K]`"));
        };
        let mut stages = 1;
        if c.eat(&Tok::Comma) {
            c.expect_word("stages")?;
            stages = c.uint("a stage count", u64::from(u8::MAX))?.0 as u8;
        }
        c.expect(Tok::Colon)?;
        end_of_line(c)?;
        Ok(LoopBegin { kind, stages })
    }

    fn instruction(&self, c: &mut Cursor<'_>) -> Result<(Instruction, Where), AsmError> {
        let mut ins = self.empty();
        let mut w = Where {
            line: c.pos(),
            parts: Vec::new(),
        };
        loop {
            let (slot, pos) = c.ident("a slot (`add0`, `sin0`, `imm`, …)")?;
            if w.parts.iter().any(|(n, _)| *n == slot) {
                return Err(error(
                    pos,
                    format!("slot `{slot}` appears twice in one instruction"),
                ));
            }
            w.parts.push((slot.clone(), pos));
            self.slot(c, &slot, pos, &mut ins, &mut w)?;
            if c.at_end() {
                return Ok((ins, w));
            }
            if !c.eat(&Tok::Bar) {
                return Err(c.unexpected("`|` or the end of the instruction"));
            }
        }
    }

    fn slot(
        &self,
        c: &mut Cursor<'_>,
        slot: &str,
        pos: Pos,
        ins: &mut Instruction,
        w: &mut Where,
    ) -> Result<(), AsmError> {
        let sh = &self.shape;
        let mut part = |field: &str, p: Pos| w.parts.push((format!("{slot}.{field}"), p));
        if let Some(k) = sh.fu_index(slot) {
            let (mnemonic, op_pos) = c.ident("an op mnemonic")?;
            let op: Op = mnemonic
                .parse()
                .map_err(|e: crate::ops::UnknownOp| error(op_pos, e.to_string()))?;
            part("op", op_pos);
            let mut s = FuSlot {
                op,
                a: 0,
                b: 0,
                cc: 0,
                dests: [None; 2],
                stage: 0,
            };
            if op == Op::Select {
                let (cc, p) = c.indexed("cc")?;
                part("cc", p);
                s.cc = cc;
                c.expect(Tok::Comma)?;
            }
            let (a, p) = c.indexed("a")?;
            part("a", p);
            s.a = a;
            if op.arity() >= 2 {
                c.expect(Tok::Comma)?;
                let (b, p) = c.indexed("b")?;
                part("b", p);
                s.b = b;
            }
            s.dests = self.dests(c, &mut part)?;
            s.stage = stage(c, &mut part)?;
            ins.fu[k] = Some(s);
        } else if let Some(k) = slot.strip_prefix("sp").and_then(parse_index) {
            if k >= sh.scratchpads {
                return Err(unknown_slot(pos, slot, sh));
            }
            let write = if c.eat_word("st") {
                true
            } else if c.eat_word("ld") {
                false
            } else {
                return Err(c.unexpected("`ld` or `st`"));
            };
            let (base, p) = c.uint("a base address", u64::from(u16::MAX))?;
            part("base", p);
            let mut s = SpSlot {
                write,
                base: base as u16,
                offset: None,
                data: 0,
                dests: [None; 2],
                stage: 0,
            };
            if matches!(c.toks.get(c.i + 1), Some(Token { tok: Tok::Ident(n), .. }) if n == "addr")
                && c.eat(&Tok::Comma)
            {
                let (o, p) = c.indexed("addr")?;
                part("addr", p);
                s.offset = Some(o);
            }
            if write {
                c.expect(Tok::Comma)?;
                let (d, p) = c.indexed("data")?;
                part("data", p);
                s.data = d;
                if c.peek_tok() == Some(&Tok::Arrow) {
                    return Err(error(c.pos(), "a scratchpad write (`st`) has no result"));
                }
            } else {
                s.dests = self.dests(c, &mut part)?;
            }
            s.stage = stage(c, &mut part)?;
            ins.sp[k] = Some(s);
        } else if let Some(k) = slot.strip_prefix("comm").and_then(parse_index) {
            if k >= sh.comm_units {
                return Err(unknown_slot(pos, slot, sh));
            }
            let (data, p) = c.indexed("data")?;
            part("data", p);
            c.expect(Tok::Comma)?;
            let p = c.pos();
            part("perm", p);
            let perm = if c.eat_word("rotate") {
                Permutation::Rotate(c.u16("a rotation")?)
            } else if c.eat_word("xor") {
                Permutation::Xor(c.u16("an xor mask")?)
            } else if c.eat_word("bcast") {
                Permutation::Broadcast(c.u16("a cluster")?)
            } else if matches!(c.peek_tok(), Some(Tok::Ident(n)) if n == "perm") {
                Permutation::PerCluster(c.indexed("perm")?.0)
            } else {
                return Err(c.unexpected("`rotate K`, `xor K`, `bcast K` or `perm[i]`"));
            };
            let dests = self.dests(c, &mut part)?;
            let stage = stage(c, &mut part)?;
            ins.comm[k] = Some(CommSlot {
                data,
                perm,
                dests,
                stage,
            });
        } else if let Some(k) = slot.strip_prefix("sin").and_then(parse_index) {
            if k >= sh.stream_ins {
                return Err(unknown_slot(pos, slot, sh));
            }
            let (name, p) = c.ident("an input stream's name")?;
            part("stream", p);
            let stream = self.stream(&name, p)?;
            let cond = cond(c, &mut part)?;
            let dests = self.dests(c, &mut part)?;
            let stage = stage(c, &mut part)?;
            ins.sin[k] = Some(StreamIn {
                stream,
                cond,
                dests,
                stage,
            });
        } else if slot == "sout" {
            let (name, p) = c.ident("an output stream's name")?;
            part("stream", p);
            let stream = self.stream(&name, p)?;
            c.expect(Tok::Comma)?;
            let (data, p) = c.indexed("data")?;
            part("data", p);
            let cond = cond(c, &mut part)?;
            let stage = stage(c, &mut part)?;
            ins.sout = Some(StreamOut {
                stream,
                data,
                cond,
                stage,
            });
        } else if slot == "imm" {
            let p = c.pos();
            part("value", p);
            let value = match c.peek() {
                Some(Token {
                    tok: Tok::Ident(v), ..
                }) if v == "cid" => ImmValue::ClusterId,
                Some(Token {
                    tok: Tok::Num(v), ..
                }) => ImmValue::Const(parse_word(v).map_err(|m| error(p, m))?),
                _ => {
                    return Err(c.unexpected("an immediate (decimal, 0x hex, a float, or `cid`)"));
                }
            };
            c.i += 1;
            let dests = self.dests(c, &mut part)?;
            let stage = stage(c, &mut part)?;
            ins.imm = Some(Immediate {
                value,
                dests,
                stage,
            });
        } else {
            return Err(unknown_slot(pos, slot, sh));
        }
        Ok(())
    }

    /// `[-> DEST[, DEST]]`.
    fn dests(
        &self,
        c: &mut Cursor<'_>,
        part: &mut impl FnMut(&str, Pos),
    ) -> Result<Dests, AsmError> {
        let mut dests = [None; 2];
        if !c.eat(&Tok::Arrow) {
            return Ok(dests);
        }
        for (d, slot) in dests.iter_mut().enumerate() {
            if d == 1 && !c.eat(&Tok::Comma) {
                break;
            }
            let (word, p) = c.ident("a destination (`add0.a[3]`, `cc[2]` or `stream NAME`)")?;
            part(&format!("dest{d}"), p);
            *slot = Some(match word.as_str() {
                "stream" => {
                    let (name, p) = c.ident("an output stream's name")?;
                    Dest::Stream {
                        stream: self.stream(&name, p)?,
                    }
                }
                "cc" => {
                    c.i -= 1;
                    Dest::Cc {
                        index: c.indexed("cc")?.0,
                    }
                }
                lrf => {
                    let Some(index) = self.shape.lrf_index(lrf) else {
                        return Err(error(
                            p,
                            format!(
                                "`{lrf}` is not an LRF of machine `{}` (its LRFs are {})",
                                self.desc.name,
                                self.shape.lrf_names.join(", ")
                            ),
                        ));
                    };
                    c.i -= 1;
                    Dest::Lrf {
                        lrf: index as u16,
                        entry: c.indexed(lrf)?.0,
                    }
                }
            });
        }
        if c.peek_tok() == Some(&Tok::Comma) {
            return Err(error(c.pos(), "a result has at most two destinations"));
        }
        Ok(dests)
    }
}

/// `[if cc[K]]`.
fn cond(c: &mut Cursor<'_>, part: &mut impl FnMut(&str, Pos)) -> Result<Option<u16>, AsmError> {
    if !c.eat_word("if") {
        return Ok(None);
    }
    let (cc, p) = c.indexed("cc")?;
    part("cond", p);
    Ok(Some(cc))
}

/// `[@S]`.
fn stage(c: &mut Cursor<'_>, part: &mut impl FnMut(&str, Pos)) -> Result<u8, AsmError> {
    let p = c.pos();
    if !c.eat(&Tok::At) {
        return Ok(0);
    }
    part("stage", p);
    Ok(c.uint("a stage", u64::from(u8::MAX))?.0 as u8)
}

fn end_of_line(c: &Cursor<'_>) -> Result<(), AsmError> {
    if c.at_end() {
        Ok(())
    } else {
        Err(c.unexpected("the end of the line"))
    }
}

fn unknown_slot(pos: Pos, slot: &str, sh: &Shape) -> AsmError {
    let range = |prefix: &str, n: usize| match n {
        1 => format!("{prefix}0"),
        n => format!("{prefix}0..{prefix}{}", n - 1),
    };
    let mut slots = vec![
        range("add", sh.adders),
        range("mul", sh.multipliers),
        range("dsq", sh.divsqrt),
        range("sp", sh.scratchpads),
        range("comm", sh.comm_units),
        range("sin", sh.stream_ins),
    ];
    slots.retain(|s| !s.is_empty());
    error(
        pos,
        format!(
            "unknown slot `{slot}`: the slots are {}, sout, imm",
            slots.join(", ")
        ),
    )
}

// ---- disassembler ---------------------------------------------------------------------

/// Prints `program` as assembly text for `desc` (see the [module documentation](self)).
/// Exact for programs that pass [`Program::check`]; any other program is printed as well as
/// it can be (names of things that do not exist are shown as `#N`) and may not assemble.
pub fn disassemble(program: &Program, desc: &MachineDesc) -> String {
    let sh = Shape::new(desc);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "; kernel {}: {} instruction{} for machine `{}`",
        program.name,
        program.code.len(),
        if program.code.len() == 1 { "" } else { "s" },
        desc.name
    );
    let _ = writeln!(out, "kernel {}", program.name);
    for s in &program.streams {
        let dir = match s.dir {
            StreamDir::In => "in",
            StreamDir::Out => "out",
        };
        let _ = writeln!(out, "{dir} {}", s.name);
    }
    out.push('\n');
    let stream = |s: u16| match program.streams.get(usize::from(s)) {
        Some(d) => d.name.clone(),
        None => format!("#{s}"),
    };
    let mut depth = 0usize;
    for (i, ins) in program.code.iter().enumerate() {
        if let Some(LoopBegin { kind, stages }) = ins.control.begin {
            let head = match kind {
                LoopKind::Counted(n) => format!("count {n}"),
                LoopKind::UntilStreamEmpty(s) => format!("stream {}", stream(s)),
                LoopKind::UntilCc(cc) => format!("until cc[{cc}]"),
            };
            let stages = if stages == 1 {
                String::new()
            } else {
                format!(", stages {stages}")
            };
            let _ = writeln!(
                out,
                "{:indent$}loop {head}{stages}:",
                "",
                indent = 4 * depth
            );
            depth += 1;
        }
        // The short form of `done` after an `end` (see the module documentation).
        let bare_done = ins.control == Control::DONE
            && ins.is_empty()
            && (i == 0 || !program.code[i - 1].control.is_next());
        if !bare_done {
            let _ = writeln!(
                out,
                "{:indent$}{}",
                "",
                instruction_text(ins, &sh, &stream),
                indent = 4 * (depth + 1)
            );
        }
        if ins.control.pass_end {
            let _ = writeln!(
                out,
                "{:indent$}pass",
                "",
                indent = 4 * depth.saturating_sub(1)
            );
        }
        if ins.control.end {
            depth = depth.saturating_sub(1);
            let _ = writeln!(out, "{:indent$}end", "", indent = 4 * depth);
        }
        if ins.control.done {
            out.push_str("done\n");
        }
    }
    out
}

/// One instruction's slots, `|`-separated, or `nop`.
fn instruction_text(ins: &Instruction, sh: &Shape, stream: &dyn Fn(u16) -> String) -> String {
    let mut slots = Vec::new();
    let mut comment = None;
    let dests = |d: &Dests| {
        let ds: Vec<String> = d
            .iter()
            .flatten()
            .map(|d| match *d {
                Dest::Lrf { lrf, entry } => match sh.lrf_names.get(usize::from(lrf)) {
                    Some(name) => format!("{name}[{entry}]"),
                    None => format!("#{lrf}[{entry}]"),
                },
                Dest::Cc { index } => format!("cc[{index}]"),
                Dest::Stream { stream: s } => format!("stream {}", stream(s)),
            })
            .collect();
        if ds.is_empty() {
            String::new()
        } else {
            format!(" -> {}", ds.join(", "))
        }
    };
    let stage = |s: u8| {
        if s == 0 {
            String::new()
        } else {
            format!(" @{s}")
        }
    };
    let cond = |c: Option<u16>| c.map_or(String::new(), |c| format!(" if cc[{c}]"));
    for (k, s) in ins.fu.iter().enumerate() {
        let Some(s) = s else { continue };
        let operands = match (s.op, s.op.arity()) {
            (Op::Select, _) => format!("cc[{}], a[{}], b[{}]", s.cc, s.a, s.b),
            (_, 1) => format!("a[{}]", s.a),
            _ => format!("a[{}], b[{}]", s.a, s.b),
        };
        slots.push(format!(
            "{} {} {operands}{}{}",
            sh.fu_name(k),
            s.op,
            dests(&s.dests),
            stage(s.stage)
        ));
    }
    for (k, s) in ins.sp.iter().enumerate() {
        let Some(s) = s else { continue };
        let offset = s.offset.map_or(String::new(), |o| format!(", addr[{o}]"));
        let body = if s.write {
            format!("st {}{offset}, data[{}]", s.base, s.data)
        } else {
            format!("ld {}{offset}{}", s.base, dests(&s.dests))
        };
        slots.push(format!("sp{k} {body}{}", stage(s.stage)));
    }
    for (k, s) in ins.comm.iter().enumerate() {
        let Some(s) = s else { continue };
        let perm = match s.perm {
            Permutation::Rotate(r) => format!("rotate {r}"),
            Permutation::Xor(x) => format!("xor {x}"),
            Permutation::Broadcast(b) => format!("bcast {b}"),
            Permutation::PerCluster(e) => format!("perm[{e}]"),
        };
        slots.push(format!(
            "comm{k} data[{}], {perm}{}{}",
            s.data,
            dests(&s.dests),
            stage(s.stage)
        ));
    }
    for (k, s) in ins.sin.iter().enumerate() {
        let Some(s) = s else { continue };
        slots.push(format!(
            "sin{k} {}{}{}{}",
            stream(s.stream),
            cond(s.cond),
            dests(&s.dests),
            stage(s.stage)
        ));
    }
    if let Some(s) = &ins.sout {
        slots.push(format!(
            "sout {}, data[{}]{}{}",
            stream(s.stream),
            s.data,
            cond(s.cond),
            stage(s.stage)
        ));
    }
    if let Some(s) = &ins.imm {
        let value = match s.value {
            ImmValue::ClusterId => "cid".to_string(),
            ImmValue::Const(v) => {
                comment = Some(imm_comment(v));
                format!("{v:#010x}")
            }
        };
        slots.push(format!("imm {value}{}{}", dests(&s.dests), stage(s.stage)));
    }
    let mut text = if slots.is_empty() {
        "nop".to_string()
    } else {
        slots.join(" | ")
    };
    if let Some(c) = comment {
        let _ = write!(text, "  ; {c}");
    }
    text
}

/// How an immediate reads: a small integer as an integer, anything else as fp32.
fn imm_comment(v: u32) -> String {
    let i = v as i32;
    if (-65536..=65536).contains(&i) {
        format!("int {i}")
    } else {
        format!("f32 {:?}", f32::from_bits(v))
    }
}

#[cfg(test)]
mod tests {
    use super::{parse_f32_word, parse_word};

    #[test]
    fn fp32_words_read_decimal_integers_as_floats_and_hex_as_bits() {
        assert_eq!(parse_word("10"), Ok(10));
        assert_eq!(parse_f32_word("10"), Ok(10.0f32.to_bits()));
        assert_eq!(parse_f32_word("-10"), Ok((-10.0f32).to_bits()));
        assert_eq!(parse_f32_word("0"), Ok(0));
        assert_eq!(parse_f32_word("16777217"), Ok(16777216.0f32.to_bits()));
        assert_eq!(parse_f32_word("0x41200000"), Ok(10.0f32.to_bits()));
        assert_eq!(parse_f32_word("2.5"), parse_word("2.5"));
        let e = parse_f32_word(&"9".repeat(40)).unwrap_err();
        assert!(e.contains("beyond the range of fp32"), "{e}");
        let e = parse_f32_word("1e-50").unwrap_err();
        assert!(e.contains("rounds to zero"), "{e}");
        assert!(parse_f32_word("-").is_err());
        assert!(parse_f32_word("1x").is_err());
    }
}
