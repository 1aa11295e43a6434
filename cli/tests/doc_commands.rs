//! Commands that cannot rot: every `dispmap` command shown in a `sh` code block of
//! `README.md` or `docs/*.md` runs against the built binary, with validation on, and must
//! exit with 0. The rules a page's author relies on are in `docs/cli.md` ("Commands in the
//! documentation"):
//!
//! * only `sh` blocks are read; a command is a line starting with `dispmap` (optionally
//!   after `VAR=value` assignments), continued by a trailing `\`, ended by a `#` word;
//! * each runs in a fresh temporary folder with `DISPMAP_VALIDATION=1`; arguments naming
//!   a file of the repository get its path in the checkout;
//! * frames are made small: `render` and `demo` get `--size 64x36`, `dispmap` alone runs
//!   as `dispmap demo --size 64x36`, `bench` as a tiny sweep (one frame, one pass, one
//!   setting, a 256 map-size sweep unless `none`);
//! * `dispmap view` runs headless (`--size 64x36 --frames 3`: it exits by itself) on the
//!   session's display, or on an Xvfb server the test starts; where neither exists the
//!   test prints why it skipped it (a failure where `DISPMAP_NO_SKIP=1`, as in CI).

#[path = "support/skip.rs"]
mod skip;
#[path = "support/xvfb.rs"]
mod xvfb;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The frame size every rendering command is given.
const SMALL_SIZE: &str = "64x36";
/// A command that runs longer than this fails (the whole test should take a couple of
/// minutes on lavapipe).
const COMMAND_LIMIT: Duration = Duration::from_secs(120);
/// Options whose value is an output path (never rewritten to a repository path).
const OUTPUT_OPTIONS: &[&str] = &[
    "--out",
    "--out-dir",
    "--metrics",
    "--heatmap",
    "--interval-map",
    "--depth-out",
];

/// One command found in a page.
#[derive(Debug, Clone, PartialEq)]
struct DocCommand {
    /// `README.md:12`.
    origin: String,
    /// `VAR=value` assignments before `dispmap`.
    env: Vec<(String, String)>,
    /// The words after `dispmap`.
    args: Vec<String>,
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("cli/ has a parent")
        .to_path_buf()
}

/// README.md and every docs/*.md, sorted.
fn pages() -> Vec<PathBuf> {
    let root = repo();
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .expect("docs/ exists")
        .map(|e| e.expect("docs/ entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    let mut all = vec![root.join("README.md")];
    all.extend(docs);
    all
}

fn is_assignment(word: &str) -> bool {
    match word.split_once('=') {
        Some((name, _)) => {
            !name.is_empty()
                && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
                && !name.starts_with(|c: char| c.is_ascii_digit())
        }
        None => false,
    }
}

/// The `dispmap` commands of the `sh` blocks of `text` (`name` labels their origin).
fn extract(name: &str, text: &str) -> Vec<DocCommand> {
    let mut commands = Vec::new();
    let mut fence: Option<String> = None;
    let mut pending: Option<(usize, String)> = None;
    for (index, line) in text.lines().enumerate() {
        let number = index + 1;
        let trimmed = line.trim_start();
        if let Some(info) = trimmed.strip_prefix("```") {
            fence = match fence {
                Some(_) => None,
                None => Some(
                    info.split(|c: char| c == ',' || c.is_whitespace())
                        .next()
                        .unwrap_or("")
                        .to_string(),
                ),
            };
            assert!(
                pending.is_none(),
                "{name}:{number}: a `\\` continuation runs into the end of its code block"
            );
            continue;
        }
        if fence.as_deref() != Some("sh") {
            continue;
        }
        let (start, mut logical) = pending.take().unwrap_or((number, String::new()));
        match line.trim_end().strip_suffix('\\') {
            Some(head) => {
                logical.push_str(head);
                logical.push(' ');
                pending = Some((start, logical));
                continue;
            }
            None => logical.push_str(line),
        }
        let words = shlex::split(&logical)
            .unwrap_or_else(|| panic!("{name}:{start}: unbalanced quotes in `{logical}`"));
        let words: Vec<String> = words
            .into_iter()
            .take_while(|w| !w.starts_with('#'))
            .collect();
        let mut env = Vec::new();
        let mut rest = words.as_slice();
        while let Some((first, tail)) = rest.split_first() {
            if !is_assignment(first) {
                break;
            }
            let (k, v) = first.split_once('=').expect("an assignment");
            env.push((k.to_string(), v.to_string()));
            rest = tail;
        }
        if rest.first().map(String::as_str) == Some("dispmap") {
            commands.push(DocCommand {
                origin: format!("{name}:{start}"),
                env,
                args: rest[1..].to_vec(),
            });
        }
    }
    commands
}

/// Sets `--name value`, replacing the command's own value (`--name v` or `--name=v`).
fn set_option(args: &mut Vec<String>, name: &str, value: &str) {
    let eq = format!("{name}=");
    if let Some(i) = args.iter().position(|a| a == name) {
        if i + 1 < args.len() {
            args[i + 1] = value.to_string();
        } else {
            args.push(value.to_string());
        }
    } else if let Some(i) = args.iter().position(|a| a.starts_with(&eq)) {
        args[i] = format!("{eq}{value}");
    } else {
        args.push(name.to_string());
        args.push(value.to_string());
    }
}

fn option_value<'a>(args: &'a [String], name: &str) -> Option<&'a str> {
    let eq = format!("{name}=");
    args.iter().enumerate().find_map(|(i, a)| {
        if a == name {
            args.get(i + 1).map(String::as_str)
        } else {
            a.strip_prefix(&eq)
        }
    })
}

/// The arguments the test runs: small frames, repository paths made absolute.
fn adapt(args: &[String], root: &Path) -> Vec<String> {
    let mut args: Vec<String> = if args.is_empty() {
        vec!["demo".into()]
    } else {
        args.to_vec()
    };
    match args[0].as_str() {
        "render" | "demo" => set_option(&mut args, "--size", SMALL_SIZE),
        // The viewer runs headless: a few frames, then it exits by itself.
        "view" => {
            set_option(&mut args, "--size", SMALL_SIZE);
            set_option(&mut args, "--frames", "3");
        }
        "bench" => {
            set_option(&mut args, "--size", SMALL_SIZE);
            set_option(&mut args, "--frames", "1");
            set_option(&mut args, "--repeat", "1");
            set_option(&mut args, "--error-frames", "1");
            set_option(&mut args, "--steps", "10");
            if option_value(&args, "--sizes") != Some("none") {
                set_option(&mut args, "--sizes", "256");
            }
        }
        _ => {}
    }
    let mut previous: Option<String> = None;
    for arg in args.iter_mut() {
        let after_output = previous
            .as_deref()
            .is_some_and(|p| OUTPUT_OPTIONS.contains(&p));
        previous = Some(arg.clone());
        if after_output || arg.starts_with('-') || Path::new(arg.as_str()).is_absolute() {
            continue;
        }
        let in_repo = root.join(arg.as_str());
        if in_repo.is_file() {
            *arg = in_repo.to_string_lossy().into_owned();
        }
    }
    args
}

fn scratch(n: usize) -> PathBuf {
    let dir = std::env::temp_dir()
        .join(format!("dispmap-doc-commands-{}", std::process::id()))
        .join(n.to_string());
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

fn tail(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let start = text.len().saturating_sub(2000);
    let start = (start..=text.len())
        .find(|&i| text.is_char_boundary(i))
        .unwrap_or(text.len());
    text[start..].to_string()
}

/// The display `dispmap view` commands run on: the session's, or an Xvfb server started
/// for them; `Err` says why there is none.
fn view_display(bin: &str) -> Result<(String, Option<xvfb::Xvfb>), String> {
    let has_view = Command::new(bin)
        .args(["view", "--help"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !has_view {
        return Err("the binary has no `view` subcommand".into());
    }
    if let Some(display) = std::env::var_os("DISPLAY").filter(|s| !s.is_empty()) {
        return Ok((display.to_string_lossy().into_owned(), None));
    }
    let server = xvfb::start_xvfb()?;
    Ok((server.display.clone(), Some(server)))
}

/// Runs one command; `Err` says why it failed.
fn run(
    bin: &str,
    cmd: &DocCommand,
    args: &[String],
    dir: &Path,
    display: Option<&str>,
) -> Result<(), String> {
    let (out, err) = (dir.join("stdout.txt"), dir.join("stderr.txt"));
    let mut command = Command::new(bin);
    if let Some(display) = display {
        command
            .env("DISPLAY", display)
            .env_remove("WAYLAND_DISPLAY");
    }
    let mut child = command
        .args(args)
        .current_dir(dir)
        .env("DISPMAP_VALIDATION", "1")
        .envs(cmd.env.iter().map(|(k, v)| (k.as_str(), v.as_str())))
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).map_err(|e| e.to_string())?)
        .stderr(std::fs::File::create(&err).map_err(|e| e.to_string())?)
        .spawn()
        .map_err(|e| format!("cannot start {bin}: {e}"))?;
    let limit = COMMAND_LIMIT;
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            return if status.success() {
                Ok(())
            } else {
                Err(format!("{status}; stderr:\n{}", tail(&err)))
            };
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!(
                "still running after {} s; stderr:\n{}",
                limit.as_secs(),
                tail(&err)
            ));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn extraction_and_small_frames_follow_the_documented_rules() {
    let page = "text\n\
        ```sh\n\
        dispmap render --heightmap assets/heightmaps/rocks_depth.jpg --convention depth \\\n    \
            --size 640x360 --out r.png   # a comment\n\
        DISPMAP_VALIDATION=1 dispmap bench --out b --sizes none\n\
        ./scripts/setup-debian.sh && cargo test\n\
        dispmap\n\
        ```\n\
        ```text\n\
        dispmap render --heightmap FILE [--steps N]\n\
        ```\n";
    let found = extract("page.md", page);
    assert_eq!(found.len(), 3, "{found:?}");
    assert_eq!(found[0].origin, "page.md:3");
    assert_eq!(found[1].env, [("DISPMAP_VALIDATION".into(), "1".into())]);
    assert!(found[2].args.is_empty());

    let root = repo();
    let render = adapt(&found[0].args, &root);
    assert_eq!(option_value(&render, "--size"), Some(SMALL_SIZE));
    assert_eq!(render.iter().filter(|a| *a == "--size").count(), 1);
    assert!(Path::new(&render[2]).is_absolute() && Path::new(&render[2]).is_file());
    assert_eq!(option_value(&render, "--out"), Some("r.png"));
    assert!(!render.iter().any(|a| a.contains('#')));

    let bench = adapt(&found[1].args, &root);
    assert_eq!(option_value(&bench, "--sizes"), Some("none"));
    assert_eq!(option_value(&bench, "--frames"), Some("1"));
    assert_eq!(option_value(&bench, "--steps"), Some("10"));
    let bench = adapt(&["bench".to_string()], &root);
    assert_eq!(option_value(&bench, "--sizes"), Some("256"));

    assert_eq!(adapt(&[], &root), ["demo", "--size", SMALL_SIZE]);
}

#[test]
fn every_documented_command_runs() {
    let bin = env!("CARGO_BIN_EXE_dispmap");
    let root = repo();
    let mut commands = Vec::new();
    let mut from_readme = 0;
    for page in pages() {
        let text = std::fs::read_to_string(&page).expect("page readable");
        let name = page
            .strip_prefix(&root)
            .unwrap_or(&page)
            .to_string_lossy()
            .into_owned();
        let found = extract(&name, &text);
        if name == "README.md" {
            from_readme = found.len();
        }
        commands.extend(found);
    }
    assert!(
        from_readme >= 3 && commands.len() >= 15,
        "expected the README's and docs/'s commands, found {} ({} in the README)",
        commands.len(),
        from_readme
    );

    // Kept alive (an Xvfb server, if one was started) until every command has run.
    let view_display = view_display(bin);
    let mut failures = Vec::new();
    let mut ran = 0;
    let started = Instant::now();
    for (n, cmd) in commands.iter().enumerate() {
        let view = cmd.args.first().map(String::as_str) == Some("view");
        if let (true, Err(reason)) = (view, &view_display) {
            skip::skip(
                &format!("{} `dispmap {}`", cmd.origin, cmd.args.join(" ")),
                reason,
            );
            continue;
        }
        let args = adapt(&cmd.args, &root);
        let dir = scratch(n);
        let t = Instant::now();
        let display = match (&view_display, view) {
            (Ok((display, _)), true) => Some(display.as_str()),
            _ => None,
        };
        let result = run(bin, cmd, &args, &dir, display);
        println!(
            "{} {:.1} s  {}: dispmap {}",
            if result.is_ok() { "ok  " } else { "FAIL" },
            t.elapsed().as_secs_f64(),
            cmd.origin,
            args.join(" ")
        );
        match result {
            Ok(()) => {
                let _ = std::fs::remove_dir_all(&dir);
                ran += 1;
            }
            Err(why) => failures.push(format!(
                "{}: `dispmap {}` (run as `dispmap {}` in {}): {why}",
                cmd.origin,
                cmd.args.join(" "),
                args.join(" "),
                dir.display()
            )),
        }
    }
    println!(
        "{ran} documented commands ran in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    if failures.is_empty() {
        let _ = std::fs::remove_dir_all(
            std::env::temp_dir().join(format!("dispmap-doc-commands-{}", std::process::id())),
        );
    }
    assert!(
        failures.is_empty(),
        "{} documented command(s) failed:\n{}",
        failures.len(),
        failures.join("\n\n")
    );
}
