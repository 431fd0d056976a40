#pragma once
/// @file
/// The thin CLI layer's shared pieces: global options, self-registering subcommands, output of the
/// command summary (human text or --json), and a TTY progress bar. Internal to src/cli.

#include <CLI/CLI.hpp>
#include <cstddef>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

namespace roe::cli {

/// Options shared by every command (DESIGN §1). Filled by main before the command runs.
struct GlobalOptions {
  bool quiet = false;   ///< -q: no progress, no human summary, warnings still on stderr
  int verbose = 0;      ///< -v (repeatable): info / debug logging
  bool json = false;    ///< --json: one JSON document on stdout, nothing else on stdout
  bool force = false;   ///< --force: allow replacing existing outputs
  std::string command;  ///< the command path, e.g. "import mocap" (set by main after parsing)
};
const GlobalOptions& globals();

/// A command's run function: returns the process exit code (0 ok, 1 check/data failure).
/// Errors are thrown as roe::Error and mapped to exit codes by main.
using RunFn = std::function<int()>;
/// Binds a command's options on its CLI11 subcommand and returns the function that runs it.
using SetupFn = RunFn (*)(CLI::App& sub);

/// Registers a subcommand at static-initialisation time. `parent` is "" for a top-level command or
/// the name of a command group (only "import" exists). `order` sorts the help listing.
struct Registrar {
  Registrar(const char* parent, const char* name, const char* description, int order, SetupFn setup);
};

/// A command that runs in a helper executable beside `roe` (it needs OpenCV or LibTorch, which `roe`
/// itself never loads): `roe` lists it in its help and replaces itself with the helper when it is asked
/// for (forward.cpp). The command's own file registers it with the same name, description and order.
struct ForwardedCommand {
  const char* parent;
  const char* name;
  const char* description;
  int order;
  const char* helper;  ///< executable name, found beside roe or in ../libexec/roe
};
inline constexpr ForwardedCommand kImportRealsenseCommand{
    "import", "realsense", "Import a RealSense recording (.bag): colour frames, IMU, intrinsics", 10,
    "roe-image"};
inline constexpr ForwardedCommand kInferCommand{
    "", "infer", "Run a PoET model bundle on a dataset's images (LibTorch + OpenCV), cached per frame", 50,
    "roe-infer"};
inline constexpr ForwardedCommand kForwardedCommands[] = {kImportRealsenseCommand, kInferCommand};

/// In `roe`: when argv names a forwarded command, execs its helper with the same arguments and does not
/// return. Returns nullptr when argv names no forwarded command; else the command it could not hand over,
/// with `error` saying why (the helper is not installed: exit 3), or with `error` empty when argv asks
/// for the command's --help, which roe then answered itself on stdout (exit 0). Global flags take no values, so the
/// command is the first word not starting with '-'.
const ForwardedCommand* forward_to_helper(int argc, char** argv, std::string& error);

/// Option validators whose messages read well ("--every: must be an integer >= 1, got '0'");
/// CLI11's PositiveNumber prints its range up to DBL_MAX in full. `kind` of number_in():
///   "positive" (> 0), "non-negative" (>= 0), "integer>=1", "integer>=0" (digits only, at most 9),
///   "fraction" ((0, 1]), "confidence" ((0.5, 1)).
CLI::Validator number_in(const std::string& kind);

/// Prints the command's result: `summary` as one JSON document with --json, otherwise `human`
/// (unless --quiet). Always to stdout. Every JSON summary carries `command`, `out` (the folder or file
/// written: the summary's own `out`, `dataset`, `output` or `outputs.dir`; null when none) and
/// `warnings` (added empty when the command has none), so that batch scripts read one set of keys.
/// `listing`: the human text is what the user asked for (--list-presets), printed even with --quiet
/// (which silences the summary of work done, not the answer to a question).
void emit(const nlohmann::json& summary, const std::string& human, bool listing = false);

/// A progress bar on stderr, drawn only when stderr is a TTY and --quiet is off.
class Progress {
 public:
  Progress(std::string label, std::size_t total);
  ~Progress();
  void update(std::size_t done);
  void finish();
  /// A callback suitable for library functions taking roe::ProgressCallback.
  std::function<void(std::size_t, std::size_t)> callback();

 private:
  std::string label_;
  std::size_t total_;
  bool enabled_;
  bool finished_ = false;
  double start_s_;
  double last_draw_s_ = -1.0;
};

}  // namespace roe::cli
