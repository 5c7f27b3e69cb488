//! GTKWave save files (`.gtkw`): which signals to show, how, and where to look first.
//!
//! A save file written next to `out.vcd` as `out.gtkw` opens with `gtkwave out.gtkw`: it
//! names the dump file, starts the view at the first dumped instant zoomed to a few dozen
//! core cycles, shows the clocks first, then the control path (the groups of the stream
//! controller `sc` and the microcontroller `uc`, and any scope with a text signal such as
//! the running kernel's name), then, open, a few signals per module that say what it is
//! doing (those registered as [`SignalDecl::glance`]: each unit's op in each cluster,
//! grouped as `top.cluster0 at a glance`), then one group per other scope (module) holding
//! that scope's selected signals, closed when there are many. 1-bit signals show in binary and vectors in hexadecimal;
//! text signals ([`Display::Text`]) as ASCII; coded fields ([`Display::Names`]: DRAM
//! commands, bank states, opcodes) through GTKWave translate filter files written next to
//! the save file (`out.gtkw` → `out-filters/N.txt`), so they show by name.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use imagine_hdl::{Display, ProbeRegistry, SignalDecl, SignalId, SignalKind};

/// GTKWave trace flags (`@…` lines, hexadecimal), from GTKWave's `TR_*` bits.
mod flags {
    pub const HEX: u32 = 0x2;
    pub const DEC: u32 = 0x4;
    pub const BIN: u32 = 0x8;
    pub const ASCII: u32 = 0x800;
    pub const FTRANSLATED: u32 = 0x2000;
    pub const RJUSTIFY: u32 = 0x20;
    pub const BLANK: u32 = 0x200;
    pub const COLLAPSED: u32 = 0x1000;
    pub const CLOSED: u32 = 0x40_0000;
    pub const GRP_BEGIN: u32 = 0x80_0000;
    pub const GRP_END: u32 = 0x100_0000;
}

/// Beyond this many signals, groups start closed so the signal list stays navigable.
const OPEN_GROUPS_MAX_SIGNALS: usize = 200;
/// The width of the waveform pane the initial zoom is computed for, in pixels: a 1600-pixel
/// window less the signal tree and the signal list.
const WAVE_PANE_PX: f64 = 980.0;
/// GTKWave shows `2^-zoom / 200` time units per pixel (its `pixelsperframe` is 200).
const GTKWAVE_ZOOM_SCALE: f64 = 200.0;
/// How many core cycles the initial view shows (fewer if the dump is shorter).
const INITIAL_CYCLES: u64 = 32;

/// Where the initial view of a save file starts and how much it shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GtkwView {
    /// Time of the first dumped instant, picoseconds.
    pub start_ps: u64,
    /// Time of the last dumped instant, picoseconds, if known.
    pub end_ps: Option<u64>,
    /// Period of the core clock, picoseconds, if known: the view then spans a few dozen
    /// core cycles.
    pub core_period_ps: Option<u64>,
}

/// The save-file path that goes with a dump: `out.vcd` → `out.gtkw`.
pub fn gtkw_path(vcd_path: &Path) -> PathBuf {
    vcd_path.with_extension("gtkw")
}

/// The name GTKWave gives a signal of a VCD written by [`crate::VcdWriter`]: the full
/// hierarchical path, with the bit range for vectors (`top.mac.s2.pp_lo[23:0]`).
pub fn gtkw_signal_name(s: &SignalDecl) -> String {
    if s.width > 1 {
        format!("{}[{}:0]", s.path, s.width - 1)
    } else {
        s.path.clone()
    }
}

/// Writes the save file for the dump at `vcd_path` (see [`gtkw_path`]) listing the
/// `selected` signals of `probes`: clocks first, then a group per scope in the order the
/// scopes were first registered, signals in registration order within a group. Returns
/// the save file's path.
pub fn write_gtkw(
    vcd_path: &Path,
    probes: &ProbeRegistry,
    selected: &[SignalId],
    view: &GtkwView,
) -> io::Result<PathBuf> {
    let path = gtkw_path(vcd_path);
    // Absolute paths for both files: GTKWave uses them to find a dump moved together with
    // its save file, too.
    let abs = |p: &Path| -> PathBuf { std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf()) };
    let save = abs(&path);
    let text = render_gtkw(&abs(vcd_path), &save, probes, selected, view);
    let filters = filter_files(&save, probes, selected);
    if let Some((first, _)) = filters.first() {
        fs::create_dir_all(first.parent().expect("a file in a directory"))?;
    }
    for (file, table) in &filters {
        let mut text = String::new();
        for (value, name) in table.iter().enumerate() {
            let _ = writeln!(text, "{value} {name}");
        }
        fs::write(file, text)?;
    }
    fs::write(&path, text)?;
    Ok(path)
}

/// The translate filter files of the coded signals among `selected`: one per distinct
/// table of names, in the order first met, in the directory `<save stem>-filters` next to
/// the save file `save`.
fn filter_files(
    save: &Path,
    probes: &ProbeRegistry,
    selected: &[SignalId],
) -> Vec<(PathBuf, &'static [&'static str])> {
    let stem = save.file_stem().unwrap_or_default().to_string_lossy();
    let dir = save.with_file_name(format!("{stem}-filters"));
    let mut tables: Vec<&'static [&'static str]> = Vec::new();
    for &id in selected {
        if let Display::Names(t) = probes.get(id).display
            && !tables.contains(&t)
        {
            tables.push(t);
        }
    }
    tables
        .into_iter()
        .enumerate()
        .map(|(i, t)| (dir.join(format!("{}.txt", i + 1)), t))
        .collect()
}

/// The text of a save file (see [`write_gtkw`]), for the dump at `dump` and the save file at
/// `save`, paths written as given.
pub fn render_gtkw(
    dump: &Path,
    save: &Path,
    probes: &ProbeRegistry,
    selected: &[SignalId],
    view: &GtkwView,
) -> String {
    let mut o = String::new();
    let mut line = |s: &str| {
        o.push_str(s);
        o.push('\n');
    };
    line("[*]");
    line(&format!(
        "[*] imagine-waves {} GTKWave save file",
        env!("CARGO_PKG_VERSION")
    ));
    line("[*]");
    line(&format!("[dumpfile] \"{}\"", dump.display()));
    line(&format!("[savefile] \"{}\"", save.display()));
    line(&format!("[timestart] {}", view.start_ps));
    line("[size] 1600 900");
    line("[pos] -1 -1");
    line(&format!("*{:.6} -1{}", zoom(view), " -1".repeat(26)));

    let decls: Vec<&SignalDecl> = selected.iter().map(|&id| probes.get(id)).collect();
    // Open the signal search tree along every scope that holds a selected signal.
    let mut opened: Vec<&str> = Vec::new();
    for s in &decls {
        let scope = s.scope();
        for (i, _) in scope
            .match_indices('.')
            .chain(std::iter::once((scope.len(), "")))
        {
            let prefix = &scope[..i];
            if !prefix.is_empty() && !opened.contains(&prefix) {
                opened.push(prefix);
            }
        }
        if opened.len() > 64 {
            break;
        }
    }
    for t in opened.iter().take(64) {
        line(&format!("[treeopen] {t}."));
    }
    line("[sst_width] 260");
    line("[signals_width] 320");
    line("[sst_expanded] 1");
    line("[sst_vpaned_height] 260");

    let mut flags_now = None;
    let mut set_flags = |o: &mut String, f: u32| {
        if flags_now != Some(f) {
            let _ = writeln!(o, "@{f:x}");
            flags_now = Some(f);
        }
    };
    let filters = filter_files(save, probes, selected);
    let trace = |o: &mut String, s: &SignalDecl, set: &mut dyn FnMut(&mut String, u32)| {
        let f = match s.display {
            Display::Text => flags::ASCII | flags::RJUSTIFY,
            Display::Names(_) => flags::FTRANSLATED | flags::DEC | flags::RJUSTIFY,
            Display::Number if s.width == 1 => flags::BIN | flags::RJUSTIFY,
            Display::Number => flags::HEX | flags::RJUSTIFY,
        };
        set(o, f);
        if let Display::Names(t) = s.display
            && let Some(i) = filters.iter().position(|(_, u)| *u == t)
        {
            let _ = writeln!(o, "^{} {}", i + 1, filters[i].0.display());
        }
        o.push_str(&gtkw_signal_name(s));
        o.push('\n');
    };

    for s in decls.iter().filter(|s| s.kind == SignalKind::Clock) {
        trace(&mut o, s, &mut set_flags);
    }
    // Scopes in the order they first appear, a scope counting as appearing with its first
    // descendant, so that a module's group comes before its sub-modules' groups.
    let mut rank: HashMap<&str, usize> = HashMap::new();
    let mut groups: HashMap<&str, Vec<&SignalDecl>> = HashMap::new();
    for s in decls.iter().filter(|s| s.kind != SignalKind::Clock) {
        let scope = s.scope();
        for (i, _) in scope
            .match_indices('.')
            .chain(std::iter::once((scope.len(), "")))
        {
            let next = rank.len();
            rank.entry(&scope[..i]).or_insert(next);
        }
        groups.entry(scope).or_default().push(s);
    }
    let mut groups: Vec<(&str, Vec<&SignalDecl>)> = groups.into_iter().collect();
    // The control path first, open; then every other scope in order.
    let control = |scope: &str, signals: &[&SignalDecl]| {
        scope.ends_with(".sc")
            || scope.ends_with(".uc")
            || signals.iter().any(|s| s.display == Display::Text)
    };
    groups.sort_by_key(|(scope, signals)| (!control(scope, signals), rank[scope]));
    // The at-a-glance signals, by their module's module, in the order those first appear.
    let mut glances: Vec<(String, Vec<&SignalDecl>)> = Vec::new();
    for s in decls.iter().filter(|s| s.glance) {
        let owner = s.scope().rsplit_once('.').map_or("", |(o, _)| o);
        let name = format!("{owner} at a glance");
        match glances.iter_mut().find(|(n, _)| *n == name) {
            Some((_, signals)) => signals.push(s),
            None => glances.push((name, vec![s])),
        }
    }
    let controls = groups
        .iter()
        .take_while(|(scope, signals)| control(scope, signals))
        .count();
    // (name, signals, open whatever their number)
    let groups: Vec<(&str, &[&SignalDecl], bool)> = groups[..controls]
        .iter()
        .map(|(scope, signals)| (*scope, &signals[..], true))
        .chain(
            glances
                .iter()
                .map(|(name, signals)| (name.as_str(), &signals[..], true)),
        )
        .chain(
            groups[controls..]
                .iter()
                .map(|(scope, signals)| (*scope, &signals[..], false)),
        )
        .collect();
    let many = decls.len() > OPEN_GROUPS_MAX_SIGNALS;
    for (scope, signals, open) in &groups {
        let closed = many && !open;
        let name = if scope.is_empty() {
            "(top level)"
        } else {
            scope
        };
        let (begin, end) = if closed {
            (
                flags::GRP_BEGIN | flags::BLANK | flags::CLOSED,
                flags::GRP_END | flags::BLANK | flags::CLOSED | flags::COLLAPSED,
            )
        } else {
            (
                flags::GRP_BEGIN | flags::BLANK,
                flags::GRP_END | flags::BLANK,
            )
        };
        set_flags(&mut o, begin);
        let _ = writeln!(o, "-{name}");
        for s in signals.iter() {
            trace(&mut o, s, &mut set_flags);
        }
        set_flags(&mut o, end);
        let _ = writeln!(o, "-{name}");
    }
    o
}

/// GTKWave's zoom for a view of about [`INITIAL_CYCLES`] core cycles (or the whole dump if
/// shorter) across the waveform pane: `2^-zoom / 200` time units per pixel.
fn zoom(view: &GtkwView) -> f64 {
    let mut span = match view.core_period_ps {
        Some(p) if p > 0 => (p * INITIAL_CYCLES) as f64,
        _ => 64_000.0,
    };
    if let Some(end) = view.end_ps {
        let dumped = end.saturating_sub(view.start_ps);
        if dumped > 0 {
            span = span.min(dumped as f64);
        }
    }
    -(GTKWAVE_ZOOM_SCALE * span / WAVE_PANE_PX).max(1.0).log2()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_clocks_and_flags() {
        let mut r = ProbeRegistry::new();
        let clk = r.register("top.clk_core".into(), 1, SignalKind::Clock);
        let a = r.register("top.mac.s1.a".into(), 16, SignalKind::Reg);
        let v = r.register("top.mac.s1.valid".into(), 1, SignalKind::Reg);
        let st = r.register("top.mac.stalled".into(), 1, SignalKind::Reg);
        let p = r.register("top.mac.s2.pp_lo".into(), 24, SignalKind::Reg);
        let text = render_gtkw(
            Path::new("/x/out.vcd"),
            Path::new("/x/out.gtkw"),
            &r,
            &[a, v, st, p, clk],
            &GtkwView {
                start_ps: 2000,
                end_ps: Some(10_000_000),
                core_period_ps: Some(2000),
            },
        );
        assert!(text.contains("[dumpfile] \"/x/out.vcd\"\n"), "{text}");
        assert!(text.contains("[timestart] 2000\n"));
        let body: Vec<&str> = text
            .lines()
            .skip_while(|l| !l.starts_with("[sst_vpaned_height]"))
            .skip(1)
            .collect();
        assert_eq!(
            body,
            [
                "@28",
                "top.clk_core",
                "@800200",
                "-top.mac",
                "@28",
                "top.mac.stalled",
                "@1000200",
                "-top.mac",
                "@800200",
                "-top.mac.s1",
                "@22",
                "top.mac.s1.a[15:0]",
                "@28",
                "top.mac.s1.valid",
                "@1000200",
                "-top.mac.s1",
                "@800200",
                "-top.mac.s2",
                "@22",
                "top.mac.s2.pp_lo[23:0]",
                "@1000200",
                "-top.mac.s2",
            ]
        );
        assert!(text.contains("[treeopen] top.\n[treeopen] top.mac.\n[treeopen] top.mac.s1.\n"));
    }

    #[test]
    fn glance_signals_come_open_after_the_control_path_and_before_closed_details() {
        let mut r = ProbeRegistry::new();
        let kernel = r.register("top.sc.kernel".into(), 64, SignalKind::Reg);
        r.set_display(kernel, Display::Text);
        let mut ids = vec![kernel];
        for c in 0..2 {
            for unit in ["add0", "mul0"] {
                let op = r.register(format!("top.cluster{c}.{unit}.op"), 7, SignalKind::Reg);
                r.set_glance(op);
                ids.push(op);
                // Enough detail signals that the detail groups start closed.
                for k in 0..OPEN_GROUPS_MAX_SIGNALS / 4 {
                    let path = format!("top.cluster{c}.{unit}.d{k}");
                    ids.push(r.register(path, 8, SignalKind::Reg));
                }
            }
        }
        let text = render_gtkw(
            Path::new("o.vcd"),
            Path::new("o.gtkw"),
            &r,
            &ids,
            &GtkwView::default(),
        );
        // Group openings in order, with whether they start closed.
        let lines: Vec<&str> = text.lines().collect();
        let groups: Vec<(&str, bool)> = lines
            .windows(2)
            .filter_map(|w| {
                let flags = u32::from_str_radix(w[0].strip_prefix('@')?, 16).ok()?;
                let name = w[1].strip_prefix('-')?;
                (flags & flags::GRP_BEGIN != 0).then_some((name, flags & flags::CLOSED != 0))
            })
            .collect();
        assert_eq!(
            groups[..4],
            [
                ("top.sc", false),
                ("top.cluster0 at a glance", false),
                ("top.cluster1 at a glance", false),
                ("top.cluster0.add0", true),
            ],
            "{groups:?}"
        );
        let glance = text.split("-top.cluster1 at a glance").nth(1).unwrap();
        assert!(glance.contains("top.cluster1.add0.op[6:0]\n"), "{glance}");
        assert!(glance.contains("top.cluster1.mul0.op[6:0]\n"), "{glance}");
    }

    #[test]
    fn zoom_shows_a_few_dozen_cycles() {
        let v = GtkwView {
            start_ps: 0,
            end_ps: None,
            core_period_ps: Some(2000),
        };
        // 32 cycles of 2 ns over 980 px: 65.3 ps per pixel.
        let ps_per_px = |z: f64| 2f64.powf(-z) / 200.0;
        assert!((ps_per_px(zoom(&v)) - 64_000.0 / 980.0).abs() < 1e-6);
        let short = GtkwView {
            end_ps: Some(6000),
            ..v
        };
        assert!((ps_per_px(zoom(&short)) - 6000.0 / 980.0).abs() < 1e-6);
    }
}
