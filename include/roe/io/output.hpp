#pragma once
/// @file
/// Safe output: nothing half-written, nothing overwritten by accident (DESIGN §7).
///  - OutputDir: a new output folder is built in a temporary sibling folder and renamed into place
///    by commit(); an existing non-empty folder is refused unless `force` is set (then it is
///    replaced only at commit time). If commit() is never reached the temporary folder is removed.
///  - write_file_atomic: one file via a temporary name in the same folder + rename.

#include <signal.h>

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "roe/io/input.hpp"  // read_file, sha256_file

namespace roe::io {

namespace fs = std::filesystem;

/// What an output path is written as: one file (replaced by a rename) or one folder (renamed into place).
enum class OutputKind { file, folder };

/// The one rule for an output path that already exists, for every command that writes: a file output
/// replaces only a regular file, a folder output only a folder. Anything else there (a device node, a FIFO,
/// a socket, a folder where a file is written, a file where a folder is) is refused with roe::InputError
/// (exit 2) whatever --force says, and left untouched: `--out /dev/null --force` never replaces the
/// machine's /dev/null with a regular file. Symlinks are followed (a link to a device is a device; a dangling
/// link is not an existing output). Nothing is opened, so a FIFO never blocks. `what` names the output in
/// the message ("--save_results file"). AtomicFile, OutputDir and StagedFiles apply it when they start and
/// again just before their rename; commands call check_file_output / OutputDir::check before any work.
void refuse_special_output(const fs::path& out, OutputKind kind, const std::string& what = "output");

/// The refusals of a file output, creating nothing, for a command that checks its output before its work:
/// refuse_special_output, then an existing file without `force`, then an output that is one of `inputs`
/// or contains one (refuse_overwriting_inputs).
void check_file_output(const fs::path& out, bool force, const std::vector<fs::path>& inputs = {},
                       const std::string& what = "output file");

class OutputDir {
 public:
  /// Throws roe::InputError if `final_dir` exists, is non-empty and force is false, or exists and is
  /// not a directory; if it is the current folder or one of its ancestors; or if it is one of
  /// `inputs` or contains one (replacing it would delete the command's own input, even with force).
  /// Trailing separators are ignored (`runs/x/` is `runs/x`).
  OutputDir(fs::path final_dir, bool force, const std::vector<fs::path>& inputs = {});
  /// The constructor's refusals alone, creating nothing: for a command that checks its output before a
  /// long computation but creates the folder only at the end.
  static void check(const fs::path& final_dir, bool force, const std::vector<fs::path>& inputs = {});
  ~OutputDir();
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;

  /// The temporary folder files are written into.
  const fs::path& tmp() const { return tmp_; }
  /// The final folder (valid after commit()).
  const fs::path& final_dir() const { return final_; }
  /// Path of `rel` inside the temporary folder; creates its parent folders.
  fs::path file(const fs::path& rel) const;
  /// Moves the finished folder into place (replacing an existing one when forced).
  void commit();
  /// Temporaries of this output that killed runs left behind, removed by the constructor.
  const std::vector<fs::path>& stale_removed() const { return stale_removed_; }

 private:
  fs::path final_;
  std::vector<fs::path> stale_removed_;
  fs::path tmp_;
  std::vector<fs::path> created_;  ///< parent folders the constructor created, deepest first
  void remove_created_parents();
  bool force_;
  bool committed_ = false;
  int slot_ = -1;  ///< signal-cleanup registration of tmp_
};

/// Removes the temporaries of `final_path` (its hidden siblings `.NAME.tmp-*`, folders or files) that
/// a process of this machine left when it was killed with SIGKILL (the OOM killer, a scheduler's
/// hard kill), and returns them. A temporary is removed only when its name is exactly one roe writes,
/// it carries this host's tag and its PID is not a live process; another host's (on a shared file
/// system) or a running process's is never touched. The backup of a replaced output (`.old`) is
/// never removed. Called by OutputDir's constructor and StagedFiles::stage.
std::vector<fs::path> remove_stale_temporaries(const fs::path& final_path);

/// Makes SIGINT, SIGTERM and SIGHUP (Ctrl-C, `timeout`, a batch scheduler's cancel) remove the
/// temporary outputs in progress (OutputDir's folder, StagedFiles' files) before the process dies
/// of the signal, so an interrupted command leaves no hidden `.NAME.tmp-*` behind. The handler only
/// forks `rm -rf` (async-signal-safe); SIGKILL cannot be caught and still leaves them. Called once
/// by the executable's main.
void remove_temporaries_on_signals();

/// A temporary file or folder this process made outside an output (e.g. the decompressed copy of a bag file
/// in $TMPDIR): while the object lives, the handler of remove_temporaries_on_signals() removes it on SIGINT,
/// SIGTERM and SIGHUP. The object's end only unregisters it; its owner removes it.
class SignalCleanup {
 public:
  explicit SignalCleanup(const fs::path& path);
  ~SignalCleanup();
  SignalCleanup(const SignalCleanup&) = delete;
  SignalCleanup& operator=(const SignalCleanup&) = delete;

 private:
  int slot_ = -1;
};

/// Registers a child process roe waits for (e.g. the plotting script; io/process.hpp) with the handler of
/// remove_temporaries_on_signals(): on SIGINT/SIGTERM/SIGHUP it kills the child and its process group
/// (SIGKILL) and reaps it before removing the temporaries. Returns a slot for unregister_child_process
/// (-1 when all 8 are taken: that child is then not killed, nothing worse).
int register_child_process(pid_t pid);
void unregister_child_process(int slot);

/// Defers SIGINT, SIGTERM and SIGHUP for its lifetime, in every thread (they arrive when it ends): a
/// sequence of renames that belong together is not cut in half. This thread blocks them; a signal that
/// another thread takes meanwhile (LibTorch's or std::async's) is recorded by the handler of
/// remove_temporaries_on_signals() and raised again when the last DeferSignals ends.
class DeferSignals {
 public:
  DeferSignals();
  ~DeferSignals();
  DeferSignals(const DeferSignals&) = delete;
  DeferSignals& operator=(const DeferSignals&) = delete;

 private:
  sigset_t old_;
};

/// An exclusive advisory lock (flock) on a folder, held for the object's lifetime. The imports that
/// read, change and rewrite a dataset's roe.json take it first, so two imports into one dataset at
/// once run one after the other instead of one silently losing the other's change. The folder must
/// exist; nothing is created in it.
class FolderLock {
 public:
  explicit FolderLock(const fs::path& dir);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int fd_ = -1;
};

/// An exclusive advisory lock (flock) on a lock file (created when missing, never removed), taken without
/// waiting: held() says whether this process got it. It is released when the object ends or the process
/// dies (a killed Slurm task releases its sweep job's lock). The file is opened read-write, so the lock
/// also holds across the clients of an NFS share (Linux emulates flock with fcntl locks there).
class FileLock {
 public:
  explicit FileLock(const fs::path& file);
  ~FileLock();
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;
  bool held() const { return fd_ >= 0; }

 private:
  int fd_ = -1;
};

/// Files that belong together (an import's data and the roe.json that records it), written under
/// temporary names beside their final paths and renamed into place by commit() in the order they
/// were staged (stage roe.json last). Until commit(), nothing the reader sees has changed; if it is
/// never reached (an error, an exception), the destructor removes the temporaries and the folders
/// that ensure_folder() and stage() created, so the dataset stays as it was.
class StagedFiles {
 public:
  StagedFiles() = default;
  ~StagedFiles();
  StagedFiles(const StagedFiles&) = delete;
  StagedFiles& operator=(const StagedFiles&) = delete;
  /// Creates `dir` (and missing parents) unless it exists, remembering what it created.
  void ensure_folder(const fs::path& dir);
  /// The temporary path to write `final_path` to (creating its parent folders).
  fs::path stage(const fs::path& final_path);
  /// Takes `dir`'s FolderLock and holds it until after the destructor's clean-up.
  void lock(const fs::path& dir);
  /// Renames every staged file into place, in order; roe::InputError when one cannot be (e.g. its
  /// final path is a folder). Then the earlier renames are undone: the files they replaced are put
  /// back (from hard-linked or copied backups taken just before each rename) and the files they added
  /// removed, so the dataset is as it was.
  void commit();

 private:
  std::optional<FolderLock> lock_;  ///< declared first: released last
  std::vector<std::pair<fs::path, fs::path>> files_;  ///< (temporary, final)
  std::vector<int> slots_;                             ///< their signal-cleanup registrations
  std::vector<fs::path> created_;                      ///< folders created, in creation order
  bool committed_ = false;
};

/// `path` without trailing separators ("runs/x/" → "runs/x"; "/" stays "/").
fs::path without_trailing_separator(const fs::path& path);

/// Throws roe::InputError when `out` (a folder or file about to be written or replaced) is one of
/// `inputs` or contains one of them. Paths are compared after resolving symlinks and `..`; inputs
/// that do not exist are ignored. `what` names the output in the message ("output folder").
void refuse_overwriting_inputs(const fs::path& out, const std::vector<fs::path>& inputs,
                               const std::string& what = "output folder");

/// True when `path` is `dir` or lies inside it, compared after resolving symlinks and `..` (neither needs
/// to exist).
bool is_within(const fs::path& path, const fs::path& dir);

/// The absolute, normalised form of an input's path (symlinks resolved where they exist), as recorded
/// in roe.json's sources[]: valid whatever folder the command ran from.
std::string provenance_path(const fs::path& path);

/// A file written through a temporary file in the same folder, renamed into place by commit(): the content
/// may come in pieces (append), so a table of any size needs only a piece's memory. The final path is
/// untouched until commit(); the destructor of an uncommitted file (an exception, a failed write) removes
/// the temporary, and so does the signal handler. Refuses to replace an existing file unless `overwrite`
/// is true (roe::InputError, at construction).
class AtomicFile {
 public:
  explicit AtomicFile(fs::path path, bool overwrite = true);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  /// roe::InputError naming the temporary when the write fails (disk full).
  void append(std::string_view bytes);
  /// Flushes, closes and renames the temporary into place; roe::InputError when that fails.
  void commit();

 private:
  void fail(const std::string& message, const fs::path& where);
  fs::path path_, tmp_;
  int fd_ = -1;
  int slot_ = -1;
};

/// Writes `content` to `path` in one piece (AtomicFile).
void write_file_atomic(const fs::path& path, std::string_view content, bool overwrite = true);

/// Lower-case hex SHA-256 of a byte string.
std::string sha256_hex(std::string_view bytes);

}  // namespace roe::io
