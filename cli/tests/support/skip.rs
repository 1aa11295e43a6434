//! Skipping what this machine cannot run (no display server, not root, no `mount`): said
//! on stderr, or a failure where [`NO_SKIP`] is set (CI sets it, so a check that stops
//! running fails instead of passing unseen).

/// The environment switch: `DISPMAP_NO_SKIP=1` turns every skip into a failure.
pub const NO_SKIP: &str = "DISPMAP_NO_SKIP";

/// Whether skipping is forbidden (`DISPMAP_NO_SKIP=1`).
pub fn forbidden() -> bool {
    std::env::var_os(NO_SKIP).is_some_and(|v| v == "1")
}

/// Skips `what` because of `why`: prints `SKIPPED what: why`, or panics with it where
/// [`NO_SKIP`] is set.
pub fn skip(what: &str, why: &str) {
    assert!(
        !forbidden(),
        "{what} cannot run here ({why}), and {NO_SKIP}=1 forbids skipping it"
    );
    eprintln!("SKIPPED {what}: {why}");
}
