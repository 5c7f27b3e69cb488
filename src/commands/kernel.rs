//! `imagine kernel`: the kernel library (list, show its compiled schedule, check it on the
//! machine against the interpreter), and microcode assembly, disassembly and runs.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Subcommand, ValueEnum};
use imagine_units::desc::MachineDesc;
use imagine_units::limits::{MAX_CHECK_ROWS, MAX_INPUT_WORDS, read_file, read_text_file};
use imagine_units::microcode::asm::{assemble, disassemble, parse_word};
use imagine_units::microcode::image::{read_image, write_image};
use imagine_units::microcode::layout::InstructionLayout;
use imagine_units::microcode::{Program, StreamDir};
use imagine_units::runner::{RunOptions, run_kernel};

use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::kernels::{LibraryKernel, find, library};
use imagine_pipelines::run::check;

use super::outputs::Outputs;
use super::waves::WaveArgs;

#[derive(Subcommand)]
pub enum KernelCommand {
    /// Assemble microcode text (.uc) into a binary microcode image
    Asm {
        /// Microcode assembly file
        file: PathBuf,
        /// Output image (default: FILE with extension .imuc)
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Machine name or description file
        #[arg(long, default_value = "gold8")]
        machine: String,
        /// Also print the instruction word layout
        #[arg(long)]
        layout: bool,
    },
    /// Disassemble a microcode image (or normalise a .uc file) into text
    Disasm {
        file: PathBuf,
        #[arg(long, default_value = "gold8")]
        machine: String,
    },
    /// Run a microcode program (.uc or image) on given input streams
    Run {
        file: PathBuf,
        #[arg(long, default_value = "gold8")]
        machine: String,
        /// An input stream: NAME=V,V,... or NAME=@FILE (values separated by commas or
        /// whitespace; decimal, 0x hex, or floats with '.' or an exponent as fp32, as the
        /// assembler reads immediates: infinities and NaNs in hex)
        #[arg(long = "input", value_name = "NAME=VALUES")]
        inputs: Vec<String>,
        /// How to print output words
        #[arg(long, value_enum, default_value_t = Format::Hex)]
        format: Format,
        /// Give up after this many core cycles
        #[arg(long, default_value_t = 10_000_000, value_parser = clap::value_parser!(u64).range(1..))]
        max_cycles: u64,
        #[command(flatten)]
        waves: WaveArgs,
    },
    /// List the kernel library
    List {
        #[arg(long)]
        json: bool,
    },
    /// Compile a library kernel and show its schedule and resource use: op counts per unit
    /// class, II bounds and achieved II, stages, ops/cycle, LRF use, the schedule table
    Show {
        /// Kernel name (see `imagine kernel list`)
        name: String,
        #[arg(long, default_value = "gold8")]
        machine: String,
        #[arg(long)]
        json: bool,
        /// Also print the microcode
        #[arg(long)]
        microcode: bool,
        /// Compile afresh: neither read nor write the compile cache
        #[arg(long)]
        no_cache: bool,
    },
    /// Run a library kernel on random inputs on the machine and in the interpreter and
    /// compare every output word
    Check {
        /// Kernel name, or `all`
        name: String,
        #[arg(long, default_value = "gold8")]
        machine: String,
        /// Loop iterations of random input
        #[arg(long, default_value_t = 4)]
        rows: usize,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long)]
        json: bool,
        /// Compile afresh: neither read nor write the compile cache
        #[arg(long)]
        no_cache: bool,
    },
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Format {
    Hex,
    F32,
    I32,
    U32,
}

fn load_program(file: &Path, desc: &MachineDesc) -> Result<Program> {
    let bytes = read_file(file).with_context(|| format!("cannot read `{}`", file.display()))?;
    if bytes.starts_with(b"IMUC") {
        return read_image(&bytes, desc).with_context(|| format!("`{}`", file.display()));
    }
    let text = String::from_utf8(bytes)
        .with_context(|| format!("`{}` is neither a microcode image nor text", file.display()))?;
    assemble(&text, desc).with_context(|| format!("{}", file.display()))
}

pub fn run(c: KernelCommand) -> Result<ExitCode> {
    match c {
        KernelCommand::Asm {
            file,
            output,
            machine,
            layout,
        } => {
            let out = output.unwrap_or_else(|| file.with_extension("imuc"));
            if out == file {
                bail!(
                    "--output `{}` is the source file itself: the image would overwrite it",
                    out.display()
                );
            }
            Outputs::default().add("--output", &out)?;
            let desc = MachineDesc::resolve(&machine)?;
            let program = load_program(&file, &desc)?;
            let image = write_image(&program, &desc);
            std::fs::write(&out, &image)
                .with_context(|| format!("cannot write `{}`", out.display()))?;
            let lay = InstructionLayout::new(&desc);
            println!(
                "kernel `{}`: {} instructions of {} bits for {}, {} bytes -> {}",
                program.name,
                program.code.len(),
                lay.width(),
                desc.name,
                image.len(),
                out.display()
            );
            if layout {
                print!("{}", lay.describe());
            }
        }
        KernelCommand::Disasm { file, machine } => {
            let desc = MachineDesc::resolve(&machine)?;
            print!("{}", disassemble(&load_program(&file, &desc)?, &desc));
        }
        KernelCommand::Run {
            file,
            machine,
            inputs,
            format,
            max_cycles,
            waves,
        } => {
            waves.check_outputs(&mut Outputs::default())?;
            let desc = MachineDesc::resolve(&machine)?;
            let program = load_program(&file, &desc)?;
            let streams = parse_inputs(&program, &inputs)?;
            let options = RunOptions {
                max_cycles,
                on_start: Some(Box::new(move |sim| {
                    waves.attach(sim).map(|_| ()).map_err(|e| format!("{e:#}"))
                })),
            };
            let start = Instant::now();
            let run = run_kernel(&desc, &program, &streams, options)?;
            let host = start.elapsed().as_secs_f64();
            let outs = program.streams.iter().filter(|s| s.dir == StreamDir::Out);
            for (s, words) in outs.zip(&run.outputs) {
                println!("{} ({} words):", s.name, words.len());
                for chunk in words.chunks(8) {
                    let line: Vec<String> = chunk.iter().map(|&w| format_word(w, format)).collect();
                    println!("  {}", line.join(" "));
                }
            }
            let s = &run.stats;
            println!(
                "cycles {} (stalled {}), instructions {}, ops/cycle {:.2}, host {:.3} s",
                s.cycles,
                s.stall_cycles,
                s.instructions,
                s.ops_per_cycle(desc.cluster.count),
                host
            );
        }
        KernelCommand::List { json } => {
            let lib = library();
            if json {
                let list: Vec<_> = lib
                    .iter()
                    .map(|k| serde_json::json!({"name": k.name, "description": k.description}))
                    .collect();
                println!("{}", serde_json::to_string_pretty(&list)?);
            } else {
                for k in lib {
                    println!("{:<12} {}", k.name, k.description);
                }
            }
        }
        KernelCommand::Show {
            name,
            machine,
            json,
            microcode,
            no_cache,
        } => {
            let desc = MachineDesc::resolve(&machine)?;
            let lk = find_kernel(&name)?;
            let compiled = cache(no_cache).compile(&(lk.build)(&desc)?, &desc)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&compiled.report)?);
            } else {
                print!("{}", compiled.report.text());
            }
            if microcode {
                print!("{}", disassemble(&compiled.program, &desc));
            }
        }
        KernelCommand::Check {
            name,
            machine,
            rows,
            seed,
            json,
            no_cache,
        } => {
            if !(1..=MAX_CHECK_ROWS).contains(&rows) {
                bail!("--rows {rows}: must be 1..={MAX_CHECK_ROWS} (MAX_CHECK_ROWS)");
            }
            let desc = MachineDesc::resolve(&machine)?;
            let cache = cache(no_cache);
            let kernels: Vec<&LibraryKernel> = if name == "all" {
                library().iter().collect()
            } else {
                vec![find_kernel(&name)?]
            };
            // Every kernel is built first, so a machine one of them cannot serve is refused
            // before anything is compiled.
            let kernels = kernels
                .into_iter()
                .map(|lk| Ok((lk, (lk.build)(&desc)?)))
                .collect::<Result<Vec<_>>>()?;
            let mut results = Vec::new();
            let mut failed = false;
            for (lk, kernel) in kernels {
                let compiled = cache.compile(&kernel, &desc)?;
                let inputs = (lk.inputs)(&desc, rows, seed);
                let check = check(&kernel, &compiled, &desc, &inputs)
                    .map_err(|e| anyhow::anyhow!("kernel `{}` on {}: {e}", lk.name, desc.name))?;
                failed |= check.mismatch.is_some();
                let r = &compiled.report;
                if json {
                    results.push(serde_json::json!({
                        "kernel": lk.name,
                        "machine": desc.name,
                        "words": check.words,
                        "pass": check.mismatch.is_none(),
                        "mismatch": check.mismatch.as_ref().map(|m| m.to_string()),
                        "cycles": check.stats.cycles,
                        "ii": r.ii,
                        "mii": r.mii(),
                        "ops_per_cycle_loop": r.ops_per_cycle,
                    }));
                } else {
                    match &check.mismatch {
                        None => println!(
                            "{}: pass on {}: {} output words equal the interpreter's \
                             ({} cycles, II {} vs bound {})",
                            lk.name,
                            desc.name,
                            check.words,
                            check.stats.cycles,
                            r.ii.map_or("-".into(), |i| i.to_string()),
                            r.mii()
                        ),
                        Some(m) => println!("{}: FAIL on {}: {m}", lk.name, desc.name),
                    }
                }
            }
            if json {
                println!("{}", serde_json::to_string_pretty(&results)?);
            }
            if failed {
                return Ok(ExitCode::FAILURE);
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The compile cache, unless `--no-cache`.
fn cache(no_cache: bool) -> CompileCache {
    if no_cache {
        CompileCache::disabled()
    } else {
        CompileCache::from_env()
    }
}

fn find_kernel(name: &str) -> Result<&'static LibraryKernel> {
    match find(name) {
        Some(k) => Ok(k),
        None => {
            let names: Vec<&str> = library().iter().map(|k| k.name).collect();
            bail!(
                "no kernel `{name}` in the library (there are: {})",
                names.join(", ")
            )
        }
    }
}

fn format_word(w: u32, format: Format) -> String {
    match format {
        Format::Hex => format!("{w:08x}"),
        Format::F32 => format!("{:?}", f32::from_bits(w)),
        Format::I32 => format!("{}", w as i32),
        Format::U32 => format!("{w}"),
    }
}

fn parse_inputs(program: &Program, args: &[String]) -> Result<Vec<Vec<u32>>> {
    let mut given: Vec<(String, Vec<u32>)> = Vec::new();
    for arg in args {
        let Some((name, values)) = arg.split_once('=') else {
            bail!("--input `{arg}`: expected NAME=VALUES or NAME=@FILE");
        };
        let text = match values.strip_prefix('@') {
            Some(path) => read_text_file(Path::new(path))
                .with_context(|| format!("--input {name}: cannot read `{path}`"))?,
            None => values.to_string(),
        };
        // The assembler's reading of an immediate: one notation, one set of errors.
        let words = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .take(MAX_INPUT_WORDS + 1)
            .map(parse_word)
            .collect::<Result<Vec<u32>, String>>()
            .map_err(|e| anyhow::anyhow!("--input {name}: {e}"))?;
        if words.len() > MAX_INPUT_WORDS {
            bail!("--input {name}: more than {MAX_INPUT_WORDS} words (MAX_INPUT_WORDS)");
        }
        given.push((name.to_string(), words));
    }
    let mut streams = Vec::new();
    for s in program.streams.iter().filter(|s| s.dir == StreamDir::In) {
        let Some(pos) = given.iter().position(|(n, _)| *n == s.name) else {
            bail!(
                "kernel `{}` needs input stream `{}` (--input {}=...)",
                program.name,
                s.name,
                s.name
            );
        };
        streams.push(given.remove(pos).1);
    }
    if let Some((extra, _)) = given.first() {
        bail!("kernel `{}` has no input stream `{extra}`", program.name);
    }
    Ok(streams)
}
