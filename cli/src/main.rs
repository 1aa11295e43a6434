//! The `dispmap` command line's entry point: process set-up, the subcommand dispatch
//! (and `info`), and the error report; each subcommand's arguments are in [`args`], its
//! body in its own file.

use anyhow::{Context as _, Result, bail};
use clap::{ArgMatches, CommandFactory, FromArgMatches};
use dispmap::context::{Context, ContextOptions};
use dispmap_cli::{bundled, output};
use std::sync::Arc;

/// `println!` of this binary: a line to standard output that records a failed write
/// instead of panicking ([`console`]).
macro_rules! println {
    () => {
        $crate::console::line($crate::console::Stream::Out, format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::console::line($crate::console::Stream::Out, format_args!($($arg)*))
    };
}

/// `eprintln!` of this binary: a line to standard error that records a failed write
/// instead of panicking ([`console`]).
macro_rules! eprintln {
    () => {
        $crate::console::line($crate::console::Stream::Err, format_args!(""))
    };
    ($($arg:tt)*) => {
        $crate::console::line($crate::console::Stream::Err, format_args!($($arg)*))
    };
}

mod args;
mod bench_cmd;
mod console;
mod demo_cmd;
mod metrics_report;
mod render_cmd;
mod render_objects;
mod view;

use args::{Cli, Command, CommonArgs, DemoArgs, RenderArgs, parse_size, validate_settings};
use bench_cmd::bench_command;
use demo_cmd::demo;
use metrics_report::{ErrorSummary, Iterations, NO_PIXELS};
use render_cmd::{render, render_inputs, timings_line};

fn main() {
    // A file size limit (`ulimit -f`) makes a write fail with EFBIG instead of killing the
    // process with SIGXFSZ, so the temporary file of an output is removed, not left.
    // SAFETY: setting a signal's disposition to SIG_IGN installs no handler code; it is
    // done before any other thread exists.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    // SIGINT, SIGTERM, SIGHUP during a commit remove its temporary files first.
    output::clean_up_on_signals();
    // A closed standard output takes no file (`--out -`): refused with the outputs.
    if console::stdout_closed_at_start() {
        output::refuse_standard_output("standard output is closed (`>&-`): nothing receives it");
    }
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let matches = Cli::command().get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    if let Err(e) = run(cli, &matches) {
        eprintln!("error: {}", error_chain(&e));
        std::process::exit(1);
    }
    // A console that could not be written fails the run, after its outputs were
    // committed.
    if let Some(failure) = console::failure() {
        eprintln!("error: {failure} (the run finished: its outputs, if any, were written)");
        std::process::exit(1);
    }
}

/// The error and its causes, `outer: inner`, skipping a cause whose text the message
/// already ends with (dispmap's errors print their source in their own message).
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = e.to_string();
    for cause in e.chain().skip(1) {
        let cause = cause.to_string();
        if !out.ends_with(&cause) {
            out = format!("{out}: {cause}");
        }
    }
    out
}

fn run(cli: Cli, matches: &ArgMatches) -> Result<()> {
    let options = ContextOptions {
        validation: None,
        device: cli.device.clone(),
    };
    match cli.command {
        Some(Command::Info) => info(&options),
        Some(Command::Render(args)) => {
            let sub = matches
                .subcommand_matches("render")
                .context("clap parsed `render` without its matches")?;
            render(&options, &args, sub)
        }
        Some(Command::Demo(args)) => demo(&options, &args),
        Some(Command::Bench(args)) => bench_command(&options, &args),
        Some(Command::View(args)) => {
            let sub = matches
                .subcommand_matches("view")
                .context("clap parsed `view` without its matches")?;
            view::run(&options, args, sub)
        }
        None => {
            let args = DemoArgs::parse_defaults();
            demo(&options, &args)
        }
    }
}

/// Destroys the context, then fails if an allocation was left or validation reported
/// anything up to and including the device's destruction (where the object tracker
/// reports leaked objects).
pub(crate) fn finish(ctx: Arc<Context>) -> Result<()> {
    let m = ctx.messages().clone();
    let left: Vec<String> = match ctx.allocator().lock() {
        Ok(allocator) => allocator
            .generate_report()
            .allocations
            .iter()
            .map(|a| a.name.clone())
            .collect(),
        Err(_) => vec!["(the allocator's lock is poisoned)".to_owned()],
    };
    // The last holder: dropping it destroys the device (every renderer is gone).
    drop(ctx);
    if !left.is_empty() {
        bail!(
            "{} GPU allocation(s) left when the device was destroyed: {}",
            left.len(),
            left.join(", ")
        );
    }
    if m.total() > 0 {
        bail!(
            "Vulkan validation reported {} error(s) and {} warning(s) (see the log above)",
            m.errors(),
            m.warnings()
        );
    }
    Ok(())
}

/// Ends a run that created `ctx`, whatever its `result`: [`finish`] runs on a refused
/// run too, so a leak or a validation message on an error path is reported (after the
/// run's own error), not dropped unchecked.
pub(crate) fn finish_with<T>(ctx: Arc<Context>, result: Result<T>) -> Result<T> {
    match (result, finish(ctx)) {
        (Ok(v), Ok(())) => Ok(v),
        (Ok(_), Err(checked)) => Err(checked),
        (Err(e), Ok(())) => Err(e),
        (Err(e), Err(checked)) => Err(anyhow::anyhow!("{}; and then: {checked}", error_chain(&e))),
    }
}

fn info(options: &ContextOptions) -> Result<()> {
    let ctx = Arc::new(Context::headless(options)?);
    let i = ctx.info();
    println!("device:               {}", i.name);
    println!("type:                 {}", i.device_type);
    println!("driver:               {}", i.driver);
    println!("api version:          {}", i.api_version);
    println!("queue family:         {}", i.queue_family_index);
    println!("timestamp period:     {} ns", i.timestamp_period_ns);
    println!("timestamp valid bits: {}", i.timestamp_valid_bits);
    println!("max image 2D:         {}", i.max_image_dimension_2d);
    println!(
        "traversal step rules: {}",
        if ctx.traversal_rules() {
            "on (a CPU device)"
        } else {
            "off (a GPU)"
        }
    );
    println!(
        "validation:           {}",
        match (ctx.validation_enabled(), ctx.has_messenger()) {
            (true, true) => "on (Khronos validation layer, messages counted)",
            (true, false) => "on (Khronos validation layer, no debug messenger)",
            (false, _) => "off (DISPMAP_VALIDATION=1 turns it on)",
        }
    );
    finish(ctx)
}
