//! `imagine kernel`: the kernels — the library's, and every kernel of the OpenGL pipeline
//! as a scene's render builds it, under the names of the render's kernel breakdown (list,
//! show the compiled schedule, check on the machine against the interpreter) — and
//! microcode assembly, disassembly and runs.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand, ValueEnum};
use imagine_units::desc::MachineDesc;
use imagine_units::limits::{MAX_CHECK_ROWS, MAX_INPUT_WORDS, read_file, read_text_file};
use imagine_units::microcode::asm::{assemble, disassemble, parse_f32_word, parse_word};
use imagine_units::microcode::image::{read_image, write_image};
use imagine_units::microcode::layout::InstructionLayout;
use imagine_units::microcode::{Program, StreamDir};
use imagine_units::runner::{RunOptions, run_kernel};

use imagine_pipelines::compile::CompileCache;
use imagine_pipelines::kernel::{Kernel, KernelInputs};
use imagine_pipelines::kernels::{LibraryKernel, library};
use imagine_pipelines::opengl::render::{
    Rasterizer, RenderOptions, kernel_description, pipeline_kernels,
};
use imagine_pipelines::reyes::frame::{self, ShadeSetup};
use imagine_pipelines::run::{check, random_inputs};
use imagine_pipelines::scene::model::PipelineKind;
use imagine_pipelines::scene::{self, LoadOptions};

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
        /// Machine name or description file whose instruction word the image is laid out for
        #[arg(long, default_value = "gold8")]
        machine: String,
        /// Also print the instruction word layout
        #[arg(long)]
        layout: bool,
    },
    /// Disassemble a microcode image (or normalise a .uc file) into text
    Disasm {
        /// Microcode image (.imuc) or assembly text (.uc)
        file: PathBuf,
        /// Machine name or description file the image was laid out for
        #[arg(long, default_value = "gold8")]
        machine: String,
    },
    /// Run a microcode program (.uc or image) on given input streams
    Run {
        /// Microcode image (.imuc) or assembly text (.uc)
        file: PathBuf,
        /// Machine name or description file to run it on
        #[arg(long, default_value = "gold8")]
        machine: String,
        /// An input stream: NAME=V,V,... or NAME=@FILE (values separated by commas or
        /// whitespace; decimal, 0x hex, or floats with '.' or an exponent as fp32, as the
        /// assembler reads immediates: infinities and NaNs in hex). With `--format f32` a
        /// decimal integer is a float too (10 is 10.0); hex stays a bit pattern
        #[arg(long = "input", value_name = "NAME=VALUES")]
        inputs: Vec<String>,
        /// How to print output words, and with f32 how to read decimal integers in the
        /// inputs (as floats)
        #[arg(long, value_enum, default_value_t = Format::Hex)]
        format: Format,
        /// Give up after this many core cycles
        #[arg(long, default_value_t = 10_000_000, value_parser = clap::value_parser!(u64).range(1..))]
        max_cycles: u64,
        #[command(flatten)]
        waves: WaveArgs,
        #[command(flatten)]
        datapath: super::datapath::DatapathArg,
    },
    /// List the kernels: the library's, then every kernel of the OpenGL pipeline as
    /// `render SCENE` builds it (SPHERE's unless --scene), under the names of the render's
    /// kernel breakdown
    List {
        /// Machine name or description file the pipeline is planned for
        #[arg(long, default_value = "gold8")]
        machine: String,
        #[command(flatten)]
        pipeline: PipelineArgs,
        /// Print the list as JSON (name, source, description)
        #[arg(long)]
        json: bool,
    },
    /// Compile a kernel (the library's or the pipeline's) and show its schedule and
    /// resource use: op counts per unit class, II against its bound, stages, ops/cycle, LRF
    /// use, the schedule table
    Show {
        /// Kernel name (see `imagine kernel list`); a pipeline kernel's own name (the one
        /// its microcode carries: `perbegin`, `compact_recycle`) shows each of that kind
        name: String,
        /// Machine name or description file to compile for
        #[arg(long, default_value = "gold8")]
        machine: String,
        #[command(flatten)]
        pipeline: PipelineArgs,
        /// Print the compiler's report as JSON
        #[arg(long)]
        json: bool,
        /// Also print the microcode
        #[arg(long)]
        microcode: bool,
        /// Compile afresh: neither read nor write the compile cache
        #[arg(long)]
        no_cache: bool,
    },
    /// Run a kernel on random inputs on the machine and in the interpreter and compare
    /// every output word (library kernels get valid inputs of their own; the pipeline's,
    /// random words of the types they read)
    Check {
        /// Kernel name (see `imagine kernel list`; a pipeline kernel's own name, such as
        /// `compact_recycle`, checks each of that kind), or `all` for every listed kernel
        name: String,
        /// Machine name or description file to compile for and run on
        #[arg(long, default_value = "gold8")]
        machine: String,
        #[command(flatten)]
        pipeline: PipelineArgs,
        /// Loop iterations of random input
        #[arg(long, default_value_t = 4)]
        rows: usize,
        /// Seed of the random inputs
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Print the results as JSON (one object per kernel)
        #[arg(long)]
        json: bool,
        /// Compile afresh: neither read nor write the compile cache
        #[arg(long)]
        no_cache: bool,
    },
}

/// Which OpenGL pipeline's kernels `kernel list|show|check` take besides the library's.
#[derive(Args)]
pub struct PipelineArgs {
    /// Take the pipeline's kernels as `render SCENE` builds them (a built-in scene, a
    /// .toml or .tri file): specialised for its vertex and fragment programs, cull mode,
    /// depth test, blend, window and batch
    #[arg(long, value_name = "SCENE", default_value = "SPHERE")]
    scene: String,
    /// Build them for an N × N window instead of the scene's (as `render --size N`: the
    /// window is a constant of the rasterization and composite kernels)
    #[arg(long, value_name = "N")]
    size: Option<u32>,
    /// The general pipeline's kernels instead of those specialised for the scene (as
    /// `render --no-specialize`)
    #[arg(long)]
    no_specialize: bool,
    /// The rasterizer kernels to take, `barycentric` or `scanline` (as `render
    /// --rasterizer`)
    #[arg(long, default_value = "barycentric", value_parser = |t: &str| t.parse::<Rasterizer>())]
    rasterizer: Rasterizer,
    /// The pipeline whose kernels to take: `opengl` or `reyes` (the scene's patches; run
    /// them on `--machine reyes`) [default: the scene's `pipeline.kind`]
    #[arg(long, value_parser = ["opengl", "reyes"])]
    pipeline: Option<String>,
    /// Reyes: the stop length `sample` is built for (as `render --stop-length`)
    #[arg(long, value_name = "L")]
    stop_length: Option<f32>,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Format {
    /// Each word as 8 hex digits
    Hex,
    /// Each word as an fp32 value (and decimal integer inputs as floats)
    F32,
    /// Each word as a signed 32-bit integer
    I32,
    /// Each word as an unsigned 32-bit integer
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
            datapath,
        } => {
            waves.check_outputs(&mut Outputs::default())?;
            let desc = MachineDesc::resolve(&machine)?;
            let program = load_program(&file, &desc)?;
            let streams = parse_inputs(&program, &inputs, format)?;
            let options = RunOptions {
                max_cycles,
                on_start: Some(Box::new(move |sim| {
                    waves.attach(sim).map(|_| ()).map_err(|e| format!("{e:#}"))
                })),
                datapath: datapath.datapath,
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
                "cycles {} (stalled {}), instructions {}, loop passes {}, ops/cycle {:.2}, \
                 host {:.3} s",
                s.cycles,
                s.stall_cycles,
                s.instructions,
                s.loop_passes,
                s.ops_per_cycle(desc.cluster.count),
                host
            );
        }
        KernelCommand::List {
            machine,
            pipeline,
            json,
        } => {
            let desc = MachineDesc::resolve(&machine)?;
            let p = Pipeline::build(&pipeline, &desc)?;
            let entries = p.catalogue(&desc);
            if json {
                let list: Vec<_> = entries
                    .iter()
                    .map(|e| {
                        serde_json::json!({
                            "name": e.name,
                            "source": e.source_name(),
                            "in_pipeline": e.in_pipeline,
                            "description": e.description,
                        })
                    })
                    .collect();
                println!("{}", serde_json::to_string_pretty(&list)?);
            } else {
                println!(
                    "library (standalone kernels; `check` gives each valid inputs of its own)"
                );
                for e in entries.iter().filter(|e| !e.pipelines_own()) {
                    list_line(&e.name, &e.description);
                }
                println!("{} (the names of its kernel breakdown)", p.title(&desc));
                match &p.kernels {
                    Ok(kernels) => {
                        for (name, _) in kernels {
                            let e = entries.iter().find(|e| &e.name == name).expect("listed");
                            if e.pipelines_own() {
                                list_line(name, &e.description);
                            } else {
                                let same = format!("{} (the library's kernel)", e.description);
                                list_line(name, &same);
                            }
                        }
                    }
                    Err(e) => println!("  cannot be built: {e}"),
                }
                for (name, why) in &p.refused {
                    list_line(name, &format!("refused on {}: {why}", desc.name));
                }
            }
        }
        KernelCommand::Show {
            name,
            machine,
            pipeline,
            json,
            microcode,
            no_cache,
        } => {
            let desc = MachineDesc::resolve(&machine)?;
            let p = Pipeline::build(&pipeline, &desc)?;
            let cache = cache(no_cache);
            let entries = p.find(&name, &desc)?;
            let (mut reports, mut listings) = (Vec::new(), String::new());
            for e in &entries {
                let kernel = e.kernel(&desc)?;
                let mut compiled = cache.compile(&kernel, &desc)?;
                compiled.report.kernel = e.name.clone();
                if json {
                    let mut v = serde_json::to_value(&compiled.report)?;
                    v["source"] = e.source_name().into();
                    v["description"] = e.description.clone().into();
                    reports.push(v);
                } else {
                    let text = compiled.report.text();
                    let (first, rest) = text.split_once('\n').unwrap_or((&text, ""));
                    println!("{first}");
                    println!("{} ({})", e.description, p.source_of(e, &desc));
                    print!("{rest}");
                }
                if microcode {
                    let listing = disassemble(&compiled.program, &desc);
                    if json {
                        listings += &listing;
                    } else {
                        print!("{listing}");
                    }
                }
            }
            if json {
                // One kernel's report as an object, as ever; several (a kernel's own name
                // that selects each of its kind) as an array.
                let v = match <[_; 1]>::try_from(reports) {
                    Ok([one]) => one,
                    Err(many) => serde_json::Value::Array(many),
                };
                println!("{}", serde_json::to_string_pretty(&v)?);
                print!("{listings}");
            }
        }
        KernelCommand::Check {
            name,
            machine,
            pipeline,
            rows,
            seed,
            json,
            no_cache,
        } => {
            if !(1..=MAX_CHECK_ROWS).contains(&rows) {
                bail!("--rows {rows}: must be 1..={MAX_CHECK_ROWS} (MAX_CHECK_ROWS)");
            }
            let desc = MachineDesc::resolve(&machine)?;
            let p = Pipeline::build(&pipeline, &desc)?;
            let cache = cache(no_cache);
            let entries = if name == "all" {
                // The library's first, so that a machine one of them cannot serve is named
                // by it; then the pipeline's, which must be buildable.
                let all = p.catalogue(&desc);
                if let Err(why) = &p.kernels {
                    for e in &all {
                        e.kernel(&desc)?;
                    }
                    bail!("{}: cannot be built: {why}", p.title(&desc));
                }
                all
            } else {
                p.find(&name, &desc)?
            };
            // Every kernel is built first, so a machine one of them cannot serve is refused
            // before anything is compiled.
            let kernels = entries
                .iter()
                .map(|e| Ok((e, e.kernel(&desc)?)))
                .collect::<Result<Vec<_>>>()?;
            let mut results = Vec::new();
            let mut failed = false;
            // Kernels the machine cannot run are named (and fail `check all`) first.
            if name == "all" {
                for (kernel, why) in &p.refused {
                    failed = true;
                    if json {
                        results.push(serde_json::json!({
                            "kernel": kernel,
                            "machine": desc.name,
                            "pass": false,
                            "refused": why,
                        }));
                    } else {
                        println!("{kernel}: REFUSED on {}: {why}", desc.name);
                    }
                }
            }
            for (e, kernel) in kernels {
                let compiled = cache.compile(&kernel, &desc)?;
                let inputs = e.inputs(&kernel, &desc, rows, seed);
                let check = check(&kernel, &compiled, &desc, &inputs).map_err(|err| {
                    anyhow::anyhow!("kernel `{}` on {}: {err}", e.name, desc.name)
                })?;
                failed |= check.mismatch.is_some();
                let r = &compiled.report;
                if json {
                    results.push(serde_json::json!({
                        "kernel": e.name,
                        "source": e.source_name(),
                        "machine": desc.name,
                        "words": check.words,
                        "pass": check.mismatch.is_none(),
                        "mismatch": check.mismatch.as_ref().map(|m| m.to_string()),
                        "cycles": check.stats.cycles,
                        "ii": r.ii,
                        "res_mii": r.res_mii,
                        "res_limit": r.res_limit,
                        "rec_mii": r.rec_mii,
                        "ops_per_cycle": r.ops_per_cycle,
                    }));
                } else {
                    match &check.mismatch {
                        None => println!(
                            "{}: pass on {}: {} output words equal the interpreter's in {} \
                             cycles; {}",
                            e.name,
                            desc.name,
                            check.words,
                            check.stats.cycles,
                            r.interval()
                        ),
                        Some(m) => println!("{}: FAIL on {}: {m}", e.name, desc.name),
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

/// A line of `kernel list`: the name, and its description beside it (under it for the
/// pipeline's longest names, texture kernels named by their textures).
fn list_line(name: &str, description: &str) {
    const WIDTH: usize = 30;
    if name.len() <= WIDTH {
        println!("  {name:<WIDTH$}  {description}");
    } else {
        println!("  {name}\n  {:<WIDTH$}  {description}", "");
    }
}

/// A kernel `kernel list|show|check` knows by name: the library's, or the pipeline's.
struct Entry {
    name: String,
    description: String,
    source: Source,
    /// Whether the pipeline calls it (under this name).
    in_pipeline: bool,
}

enum Source {
    /// A library kernel, with its builder and its valid inputs.
    Library(&'static LibraryKernel),
    /// A kernel of the pipeline, built as its render builds it.
    Pipeline(Kernel),
}

impl Entry {
    /// Whether it is the pipeline's own (not also the library's).
    fn pipelines_own(&self) -> bool {
        matches!(self.source, Source::Pipeline(_))
    }

    fn source_name(&self) -> &'static str {
        match self.source {
            Source::Library(_) => "library",
            Source::Pipeline(_) => "pipeline",
        }
    }

    /// The kernel, built for `desc` (the pipeline's were built with the pipeline).
    fn kernel(&self, desc: &MachineDesc) -> Result<Kernel> {
        Ok(match &self.source {
            Source::Library(lk) => (lk.build)(desc)?,
            Source::Pipeline(k) => k.clone(),
        })
    }

    /// `rows` iterations of inputs: the library kernel's own valid ones, or random words
    /// of the types a pipeline kernel reads — but for the Reyes `subdiv`'s saved walks
    /// (`resume`), zeros: random words there are stack depths and scratchpad addresses no
    /// walk leaves, where zeros are fresh walks, which take their (random) patches.
    fn inputs(&self, kernel: &Kernel, desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
        match &self.source {
            Source::Library(lk) => (lk.inputs)(desc, rows, seed),
            Source::Pipeline(_) => {
                let mut inputs = random_inputs(kernel, desc, rows, seed);
                if kernel.name == "subdiv"
                    && let Some(s) = kernel.streams.iter().position(|s| s.name == "resume")
                {
                    inputs.streams[s].fill(0);
                }
                inputs
            }
        }
    }
}

/// The OpenGL pipeline `--scene` names, its kernels built for the machine (or why they
/// cannot be: a machine a library kernel serves may still be one the pipeline cannot).
struct Pipeline {
    scene: String,
    reyes: bool,
    specialised: bool,
    kernels: Result<Vec<(String, Kernel)>, String>,
    /// The Reyes pipeline's kernels the machine cannot run, each with why (the others
    /// are in `kernels`).
    refused: Vec<(String, String)>,
}

impl Pipeline {
    fn build(a: &PipelineArgs, desc: &MachineDesc) -> Result<Pipeline> {
        if let Some(size) = a.size
            && (size == 0 || size > scene::MAX_WINDOW)
        {
            bail!("--size {size} is outside 1..={}", scene::MAX_WINDOW);
        }
        let scene = scene::load(
            &a.scene,
            &LoadOptions {
                size: a.size,
                subdivisions: None,
                filter: None,
            },
        )?;
        let reyes = match a.pipeline.as_deref() {
            Some(p) => p == "reyes",
            None => scene.pipeline.kind == PipelineKind::Reyes,
        };
        if !reyes && a.stop_length.is_some() {
            bail!("--stop-length is for the Reyes pipeline (`--pipeline reyes`)");
        }
        if reyes && a.no_specialize {
            bail!("--no-specialize is for the OpenGL pipeline");
        }
        let mut refused = Vec::new();
        let kernels = if reyes {
            let stop = a.stop_length.unwrap_or(scene.pipeline.stop_length);
            frame::check_stop_length(stop).context("--stop-length")?;
            ShadeSetup::of(&scene, desc.cluster.count)
                .map_err(|e| e.to_string())
                .map(|shading| {
                    let all = frame::frame_kernel_results(
                        desc,
                        scene.width,
                        scene.height,
                        stop,
                        &shading,
                    );
                    let mut built = Vec::new();
                    for (name, k) in all {
                        match k {
                            Ok(k) => built.push((name.to_string(), k)),
                            Err(e) => refused.push((name.to_string(), e.to_string())),
                        }
                    }
                    built
                })
        } else {
            let options = RenderOptions {
                specialise: !a.no_specialize,
                rasterizer: a.rasterizer,
                ..RenderOptions::default()
            };
            pipeline_kernels(&scene, desc, &options).map_err(|e| e.to_string())
        };
        Ok(Pipeline {
            scene: scene.name.clone(),
            reyes,
            specialised: !a.no_specialize,
            kernels,
            refused,
        })
    }

    /// How the list names the pipeline.
    fn title(&self, desc: &MachineDesc) -> String {
        if self.reyes {
            return format!(
                "the Reyes pipeline of `render {} --pipeline reyes` on {}",
                self.scene, desc.name
            );
        }
        format!(
            "the OpenGL pipeline of `render {}{}` on {}",
            self.scene,
            if self.specialised {
                ""
            } else {
                " --no-specialize"
            },
            desc.name
        )
    }

    /// Where a kernel comes from, for `show`.
    fn source_of(&self, e: &Entry, desc: &MachineDesc) -> String {
        match (&e.source, e.in_pipeline) {
            (Source::Library(_), false) => "the library's".into(),
            (Source::Library(_), true) => {
                format!("the library's, the same as {}", self.title(desc))
            }
            (Source::Pipeline(_), _) => self.title(desc),
        }
    }

    /// Every kernel by name: the library's, then the pipeline's (none if it cannot be
    /// built). A pipeline kernel the library also has under its name is listed once: as
    /// the library's when it is the same kernel (`filter8`), its inputs being valid ones,
    /// else as the pipeline's.
    fn catalogue(&self, desc: &MachineDesc) -> Vec<Entry> {
        let pipeline: &[(String, Kernel)] = self.kernels.as_deref().unwrap_or(&[]);
        let mut entries: Vec<Entry> = library()
            .iter()
            .filter(|lk| {
                pipeline
                    .iter()
                    .find(|(n, _)| n == lk.name)
                    .is_none_or(|(_, k)| (lk.build)(desc).as_ref() == Ok(k))
            })
            .map(|lk| Entry {
                name: lk.name.into(),
                description: lk.description.into(),
                source: Source::Library(lk),
                in_pipeline: pipeline.iter().any(|(n, _)| n == lk.name),
            })
            .collect();
        for (name, kernel) in pipeline {
            if entries.iter().any(|e| &e.name == name) {
                continue;
            }
            entries.push(Entry {
                name: name.clone(),
                description: kernel_description(name),
                source: Source::Pipeline(kernel.clone()),
                in_pipeline: true,
            });
        }
        entries
    }

    /// The kernels `name` selects: the one listed under it, or else each pipeline kernel
    /// whose own name (the one its microcode carries) it is (`perbegin`,
    /// `compact_recycle`); an error naming every listed kernel if none.
    fn find(&self, name: &str, desc: &MachineDesc) -> Result<Vec<Entry>> {
        let mut all = self.catalogue(desc);
        if let Some(i) = all.iter().position(|e| e.name == name) {
            return Ok(vec![all.swap_remove(i)]);
        }
        let kinds: Vec<Entry> = all
            .into_iter()
            .filter(|e| matches!(&e.source, Source::Pipeline(k) if k.name == name) && e.in_pipeline)
            .collect();
        if !kinds.is_empty() {
            return Ok(kinds);
        }
        if let Some((_, why)) = self.refused.iter().find(|(n, _)| n == name) {
            bail!("kernel `{name}` of {}: {why}", self.title(desc));
        }
        let library: Vec<&str> = library().iter().map(|lk| lk.name).collect();
        let pipeline = match &self.kernels {
            Ok(kernels) => {
                let names: Vec<&str> = kernels.iter().map(|(n, _)| n.as_str()).collect();
                format!("has {}", names.join(", "))
            }
            Err(e) => format!("cannot be built: {e}"),
        };
        bail!(
            "no kernel `{name}`: the library has {}; {} {pipeline} (see `imagine kernel list`)",
            library.join(", "),
            self.title(desc)
        )
    }
}

/// The compile cache, unless `--no-cache`.
fn cache(no_cache: bool) -> CompileCache {
    if no_cache {
        CompileCache::disabled()
    } else {
        CompileCache::from_env()
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

fn parse_inputs(program: &Program, args: &[String], format: Format) -> Result<Vec<Vec<u32>>> {
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
        // The assembler's reading of an immediate: one notation, one set of errors; fp32
        // streams read a decimal integer as the float it names.
        let parse = match format {
            Format::F32 => parse_f32_word,
            _ => parse_word,
        };
        let words = text
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|t| !t.is_empty())
            .take(MAX_INPUT_WORDS + 1)
            .map(parse)
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
