//! Process exit codes of the `armature` binary.

/// The command did what was asked (a solve converged).
pub const SUCCESS: i32 = 0;
/// Bad input: arguments, files, values (also clap's code for usage errors).
pub const BAD_INPUT: i32 = 2;
/// The computation ran but did not reach its goal (IK or SCvx not converged).
pub const NOT_CONVERGED: i32 = 3;
/// Writing the output failed.
pub const IO: i32 = 4;
/// Interrupted by SIGINT, SIGTERM or SIGHUP (128 + SIGINT, as shells report Ctrl-C).
pub const INTERRUPTED: i32 = 130;
