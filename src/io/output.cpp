#include "roe/io/output.hpp"

#include <fcntl.h>
#include <openssl/evp.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

#include "roe/core/error.hpp"

namespace roe::io {
namespace {

// Temporaries to remove if a signal ends the process: fixed slots the handler can read without
// allocating (a path is copied in before its flag is set).
constexpr int kSlots = 64;
constexpr std::size_t kPathMax = 4096;
char g_temp_paths[kSlots][kPathMax];
std::atomic<bool> g_temp_claimed[kSlots];  // the slot is taken (by register_temporary)
std::atomic<bool> g_temp_used[kSlots];     // its path is complete (what the handler reads)

int register_temporary(const fs::path& p) {
  const std::string s = p.string();
  if (s.size() >= kPathMax) return -1;
  for (int i = 0; i < kSlots; ++i) {
    if (g_temp_claimed[i].exchange(true)) continue;
    std::memcpy(g_temp_paths[i], s.c_str(), s.size() + 1);
    g_temp_used[i].store(true, std::memory_order_release);
    return i;
  }
  return -1;  // more than kSlots at once: not cleaned up on a signal, nothing worse
}

void unregister_temporary(int slot) {
  if (slot < 0) return;
  g_temp_used[slot].store(false, std::memory_order_release);
  g_temp_claimed[slot].store(false, std::memory_order_release);
}

// Only async-signal-safe calls: _Fork (unlike fork, it runs no atfork handlers and takes no
// malloc or stdio lock, so it cannot deadlock a multi-threaded roe), execve, waitpid, _exit.
// DeferSignals in any thread: a signal that arrives meanwhile, in whichever thread, is only recorded,
// and raised again when the last DeferSignals ends (lock-free atomics are async-signal-safe).
std::atomic<int> g_defer_depth{0};
std::atomic<int> g_deferred_signal{0};

// Child processes (process-group leaders) the handler kills before removing the temporaries.
constexpr int kChildSlots = 8;
std::atomic<pid_t> g_children[kChildSlots];

extern "C" void remove_temporaries_and_die(int sig) {
  if (g_defer_depth.load(std::memory_order_acquire) > 0) {
    int none = 0;
    g_deferred_signal.compare_exchange_strong(none, sig);
    return;
  }
  for (int i = 0; i < kChildSlots; ++i) {
    const pid_t child = g_children[i].exchange(0);
    if (child <= 0) continue;
    ::kill(-child, SIGKILL);  // its whole group: a script's own children too
    ::kill(child, SIGKILL);
    ::waitpid(child, nullptr, 0);
  }
  static char rm[] = "rm", rf[] = "-rf", dashes[] = "--";
  for (int i = 0; i < kSlots; ++i) {
    if (!g_temp_used[i].load(std::memory_order_acquire)) continue;
    const pid_t pid = ::_Fork();
    if (pid == 0) {
      char* argv[] = {rm, rf, dashes, g_temp_paths[i], nullptr};
      char* envp[] = {nullptr};
      ::execve("/bin/rm", argv, envp);
      ::_exit(127);
    }
    if (pid > 0) ::waitpid(pid, nullptr, 0);
  }
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

// 32-bit FNV-1a of this machine's host name: temporaries carry it, so a later run only ever sweeps
// the ones a dead process of this machine left (a shared file system may hold other hosts' runs).
unsigned host_tag() {
  static const unsigned tag = [] {
    char name[256] = {};
    if (::gethostname(name, sizeof name - 1) != 0) name[0] = '\0';
    unsigned h = 2166136261u;
    for (const char* c = name; *c; ++c) h = (h ^ static_cast<unsigned char>(*c)) * 16777619u;
    return h;
  }();
  return tag;
}

// ".tmp-HOST-PID-COUNTER-RANDOM" (HOST and RANDOM 8 hex digits, PID and COUNTER decimal).
std::string unique_suffix() {
  static std::atomic<unsigned> counter{0};
  std::random_device rd;
  char buf[80];
  std::snprintf(buf, sizeof buf, ".tmp-%08x-%d-%u-%08x", host_tag(), static_cast<int>(getpid()), counter++,
                rd());
  return buf;
}

// The PID of `name` when it is exactly "." + base + unique_suffix() written on this host; else 0.
long temporary_owner(const std::string& name, const std::string& base) {
  const std::string head = "." + base + ".tmp-";
  if (name.compare(0, head.size(), head) != 0) return 0;
  const std::string rest = name.substr(head.size());
  unsigned host = 0, counter = 0, random = 0;
  long pid = 0;
  int used = 0;
  if (std::sscanf(rest.c_str(), "%8x-%ld-%u-%8x%n", &host, &pid, &counter, &random, &used) != 4) return 0;
  char canonical[80];
  std::snprintf(canonical, sizeof canonical, "%08x-%ld-%u-%08x", host, pid, counter, random);
  if (static_cast<std::size_t>(used) != rest.size() || rest != canonical || host != host_tag() || pid <= 0)
    return 0;
  return pid;
}

std::string to_hex(const unsigned char* d, unsigned n) {
  static const char* k = "0123456789abcdef";
  std::string s(2 * n, '0');
  for (unsigned i = 0; i < n; ++i) {
    s[2 * i] = k[d[i] >> 4];
    s[2 * i + 1] = k[d[i] & 15];
  }
  return s;
}

class Sha256 {
 public:
  Sha256() : ctx_(EVP_MD_CTX_new()) {
    if (!ctx_ || EVP_DigestInit_ex(ctx_, EVP_sha256(), nullptr) != 1)
      throw InternalError("OpenSSL SHA-256 initialisation failed");
  }
  ~Sha256() { EVP_MD_CTX_free(ctx_); }
  void update(const void* p, std::size_t n) { EVP_DigestUpdate(ctx_, p, n); }
  std::string hex() {
    unsigned char d[EVP_MAX_MD_SIZE];
    unsigned n = 0;
    EVP_DigestFinal_ex(ctx_, d, &n);
    return to_hex(d, n);
  }

 private:
  EVP_MD_CTX* ctx_;
};

}  // namespace

SignalCleanup::SignalCleanup(const fs::path& path) : slot_(register_temporary(path)) {}
SignalCleanup::~SignalCleanup() { unregister_temporary(slot_); }

fs::path without_trailing_separator(const fs::path& path) {
  std::string s = path.string();
  while (s.size() > 1 && s.back() == '/') s.pop_back();
  return s;
}

namespace {
// `a` equals `b` or is one of its ancestors (both absolute and normal).
bool is_same_or_ancestor(const fs::path& a, const fs::path& b) {
  auto ia = a.begin(), ib = b.begin();
  for (; ia != a.end(); ++ia, ++ib) {
    if (ia->empty() && std::next(ia) == a.end()) break;  // trailing "" of "dir/"
    if (ib == b.end() || *ia != *ib) return false;
  }
  return true;
}
fs::path resolved(const fs::path& p) {
  std::error_code ec;
  fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
  if (ec) r = fs::absolute(p, ec).lexically_normal();
  return without_trailing_separator(r);
}
}  // namespace

std::string provenance_path(const fs::path& path) { return resolved(path).string(); }

bool is_within(const fs::path& path, const fs::path& dir) { return is_same_or_ancestor(resolved(dir), resolved(path)); }

void refuse_overwriting_inputs(const fs::path& out, const std::vector<fs::path>& inputs, const std::string& what) {
  const fs::path o = resolved(out);
  for (const auto& in : inputs) {
    std::error_code ec;
    if (in.empty() || !fs::exists(in, ec)) continue;
    const fs::path i = resolved(in);
    if (is_same_or_ancestor(o, i))
      throw InputError(what + (o == i ? " is" : " contains") + " the input " + in.string() +
                           ": write the output elsewhere (even --force would delete the input)",
                       {out.string()});
  }
}

namespace {
// What `t` is, in words, for the refusal of an output of the wrong kind.
const char* file_type_name(fs::file_type t) {
  switch (t) {
    case fs::file_type::regular: return "a regular file";
    case fs::file_type::directory: return "a folder";
    case fs::file_type::character: return "a character device";
    case fs::file_type::block: return "a block device";
    case fs::file_type::fifo: return "a FIFO (named pipe)";
    case fs::file_type::socket: return "a socket";
    default: return "not a regular file or folder";
  }
}
}  // namespace

void refuse_special_output(const fs::path& out, OutputKind kind, const std::string& what) {
  std::error_code ec;
  const fs::file_status st = fs::status(out, ec);  // follows symlinks; never opens the path
  if (ec && st.type() != fs::file_type::not_found)
    throw InputError(what + " cannot be examined (" + ec.message() + "): not replacing it", {out.string()});
  const fs::file_type t = st.type();
  if (t == fs::file_type::not_found || t == fs::file_type::none) return;
  const fs::file_type want = kind == OutputKind::file ? fs::file_type::regular : fs::file_type::directory;
  if (t == want) return;
  throw InputError(what + " exists and is " + file_type_name(t) + ": roe replaces only " +
                       (kind == OutputKind::file ? "a regular file" : "a folder") +
                       " there, never this (not even with --force); name another path",
                   {out.string()});
}

void check_file_output(const fs::path& out, bool force, const std::vector<fs::path>& inputs, const std::string& what) {
  if (out.empty()) throw InputError("empty " + what + " name", {out.string()});
  refuse_special_output(out, OutputKind::file, what);
  refuse_overwriting_inputs(out, inputs, what);
  std::error_code ec;
  if (!force && fs::exists(out, ec)) throw InputError(what + " already exists (use --force to replace it)", {out.string()});
}

void OutputDir::check(const fs::path& final_dir, bool force, const std::vector<fs::path>& inputs) {
  const fs::path out = without_trailing_separator(final_dir.lexically_normal());  // "a/../b/x/." → "b/x"
  std::error_code ec;
  if (out.empty()) throw InputError("empty output folder name", {final_dir.string()});
  if (is_same_or_ancestor(resolved(out), resolved(fs::current_path(ec))))
    throw InputError("output folder is the current folder or contains it: name a folder below it", {out.string()});
  refuse_overwriting_inputs(out, inputs);
  refuse_special_output(out, OutputKind::folder, "output folder");
  if (fs::exists(out, ec)) {
    if (!fs::is_empty(out, ec) && !force)
      throw InputError("output folder exists and is not empty (use --force to replace it)", {out.string()});
  }
}

OutputDir::OutputDir(fs::path final_dir, bool force, const std::vector<fs::path>& inputs)
    : final_(without_trailing_separator(final_dir.lexically_normal())), force_(force) {
  check(final_, force, inputs);
  std::error_code ec;
  fs::path parent = final_.has_parent_path() ? final_.parent_path() : fs::path(".");
  // The folders this constructor creates (deepest first): removed again, when still empty, if the
  // output is never committed. `final_` is lexically normal, so its parents are real ancestors.
  std::vector<fs::path> missing;
  for (fs::path p = parent; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  fs::create_directories(parent, ec);
  created_ = missing;
  if (ec) {
    remove_created_parents();
    throw InputError("cannot create folder: " + ec.message(), {parent.string()});
  }
  const std::string base = final_.filename().string();
  stale_removed_ = remove_stale_temporaries(final_);
  tmp_ = parent / ("." + base + unique_suffix());
  slot_ = register_temporary(tmp_);
  fs::create_directories(tmp_, ec);
  if (ec) {
    unregister_temporary(slot_);
    remove_created_parents();
    throw InputError("cannot create temporary output folder: " + ec.message(), {tmp_.string()});
  }
}

std::vector<fs::path> remove_stale_temporaries(const fs::path& final_path) {
  std::vector<fs::path> removed;
  const fs::path p = without_trailing_separator(final_path.lexically_normal());
  const std::string base = p.filename().string();
  if (base.empty() || base == "." || base == "..") return removed;
  const fs::path parent = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::error_code ec;
  fs::directory_iterator it(parent, ec), end;
  std::vector<fs::path> stale;
  for (; !ec && it != end; it.increment(ec)) {
    const long pid = temporary_owner(it->path().filename().string(), base);
    if (pid == 0 || pid == static_cast<long>(::getpid())) continue;
    if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) continue;  // alive, or not ours to judge
    stale.push_back(it->path());
  }
  for (const fs::path& s : stale) {
    std::error_code rec;
    if (fs::remove_all(s, rec) != static_cast<std::uintmax_t>(-1) && !rec) removed.push_back(s);
  }
  return removed;
}

int register_child_process(pid_t pid) {
  for (int i = 0; i < kChildSlots; ++i) {
    pid_t none = 0;
    if (g_children[i].compare_exchange_strong(none, pid)) return i;
  }
  return -1;
}

void unregister_child_process(int slot) {
  if (slot >= 0) g_children[slot].store(0);
}

void remove_temporaries_on_signals() {
  struct sigaction sa {};
  sa.sa_handler = remove_temporaries_and_die;
  sigemptyset(&sa.sa_mask);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&sa.sa_mask, sig);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    // A signal the caller ignores stays ignored (nohup, a script's background job and SIGINT).
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;
    ::sigaction(sig, &sa, nullptr);
  }
}

DeferSignals::DeferSignals() {
  sigset_t s;
  sigemptyset(&s);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&s, sig);
  ::pthread_sigmask(SIG_BLOCK, &s, &old_);
  g_defer_depth.fetch_add(1, std::memory_order_acq_rel);
}

DeferSignals::~DeferSignals() {
  const bool last = g_defer_depth.fetch_sub(1, std::memory_order_acq_rel) == 1;
  ::pthread_sigmask(SIG_SETMASK, &old_, nullptr);  // one blocked here arrives now, with nothing deferred
  if (last) {
    // One that another thread took meanwhile: deliver it now (cleanup and exit by that signal).
    if (const int sig = g_deferred_signal.exchange(0)) ::raise(sig);
  }
}

FolderLock::FolderLock(const fs::path& dir) {
  fd_ = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0) throw InputError("cannot open folder to lock it", {dir.string()});
  while (::flock(fd_, LOCK_EX) != 0) {
    if (errno == EINTR) continue;
    ::close(fd_);
    fd_ = -1;
    throw InputError("cannot lock folder", {dir.string()});
  }
}

FolderLock::~FolderLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the lock
}

FileLock::FileLock(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw InputError(std::string("cannot open lock file: ") + std::strerror(errno), {file.string()});
  int rc;
  do {
    rc = ::flock(fd, LOCK_EX | LOCK_NB);
  } while (rc != 0 && errno == EINTR);
  if (rc != 0) {
    const int err = errno;
    ::close(fd);
    if (err != EWOULDBLOCK) throw InputError(std::string("cannot lock: ") + std::strerror(err), {file.string()});
    return;  // another process holds it
  }
  fd_ = fd;
}

FileLock::~FileLock() {
  if (fd_ >= 0) ::close(fd_);
}

void StagedFiles::ensure_folder(const fs::path& dir) {
  std::error_code ec;
  std::vector<fs::path> missing;  // deepest first
  for (fs::path p = dir.lexically_normal(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  if (missing.empty()) return;
  fs::create_directories(dir, ec);
  if (ec) throw InputError("cannot create folder: " + ec.message(), {dir.string()});
  created_.insert(created_.end(), missing.rbegin(), missing.rend());
}

fs::path StagedFiles::stage(const fs::path& final_path) {
  refuse_special_output(final_path, OutputKind::file);
  if (final_path.has_parent_path()) ensure_folder(final_path.parent_path());
  (void)remove_stale_temporaries(final_path);
  fs::path tmp = final_path.parent_path() / ("." + final_path.filename().string() + unique_suffix());
  files_.emplace_back(tmp, final_path);
  slots_.push_back(register_temporary(tmp));
  return tmp;
}

void StagedFiles::commit() {
  const DeferSignals defer;
  // Each file a rename replaces is first hard-linked (or, where the file system has no hard links,
  // copied) to a backup name, so a failure part-way puts back what the earlier renames replaced and
  // removes what they added. The rename itself stays atomic: a reader never finds a final path missing.
  struct Done {
    fs::path fin, backup;  // backup empty: the final path did not exist
  };
  std::vector<Done> done;
  const auto undo = [&done] {
    std::error_code uec;
    for (auto it = done.rbegin(); it != done.rend(); ++it) {
      if (it->backup.empty())
        fs::remove(it->fin, uec);
      else
        fs::rename(it->backup, it->fin, uec);
    }
  };
  std::error_code ec;
  for (const auto& [tmp, fin] : files_) {
    try {
      refuse_special_output(fin, OutputKind::file);  // made since stage(): refused, nothing renamed over it
    } catch (const InputError& e) {
      undo();
      throw InputError(e.bare_message() + " (nothing was changed)", {fin.string()});
    }
    Done d{fin, {}};
    if (fs::is_regular_file(fs::symlink_status(fin, ec))) {
      d.backup = fin.parent_path() / ("." + fin.filename().string() + unique_suffix() + ".bak");
      fs::create_hard_link(fin, d.backup, ec);
      if (ec) {
        ec.clear();
        fs::copy_file(fin, d.backup, ec);
      }
      if (ec) {
        const std::string why = ec.message();
        fs::remove(d.backup, ec);
        undo();
        throw InputError("cannot keep a copy of the file about to be replaced: " + why, {fin.string()});
      }
    }
    fs::rename(tmp, fin, ec);
    if (ec) {
      const std::string why = ec.message();
      if (!d.backup.empty()) fs::remove(d.backup, ec);
      undo();
      throw InputError("cannot rename temporary file into place (nothing was changed): " + why, {fin.string()});
    }
    done.push_back(std::move(d));
  }
  committed_ = true;
  for (int s : slots_) unregister_temporary(s);
  for (const Done& d : done)
    if (!d.backup.empty()) fs::remove(d.backup, ec);
}

void StagedFiles::lock(const fs::path& dir) { lock_.emplace(dir); }

StagedFiles::~StagedFiles() {
  // Runs before lock_ is released: a waiting import never finds a folder this one removes.
  for (int s : slots_) unregister_temporary(s);
  if (committed_) return;
  std::error_code ec;
  for (const auto& f : files_) fs::remove(f.first, ec);
  for (auto it = created_.rbegin(); it != created_.rend(); ++it)
    if (!fs::remove(*it, ec)) break;  // no longer empty: keep it and its parents
}

void OutputDir::remove_created_parents() {
  std::error_code ec;
  for (const auto& p : created_)
    if (!fs::remove(p, ec)) break;  // fails on a folder that is no longer empty: keep it and its parents
  created_.clear();
}

OutputDir::~OutputDir() {
  unregister_temporary(slot_);
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(tmp_, ec);
    remove_created_parents();
  }
}

fs::path OutputDir::file(const fs::path& rel) const {
  fs::path p = tmp_ / rel;
  std::error_code ec;
  fs::create_directories(p.parent_path(), ec);
  if (ec) throw InputError("cannot create folder: " + ec.message(), {p.parent_path().string()});
  return p;
}

void OutputDir::commit() {
  if (committed_) return;
  const DeferSignals defer;  // not between moving the old output aside and the new one in
  refuse_special_output(final_, OutputKind::folder, "output folder");  // made meanwhile: still not replaced
  std::error_code ec;
  fs::path old;
  if (fs::exists(final_, ec)) {
    if (!fs::is_empty(final_, ec) && !force_)
      throw InputError("output folder appeared while writing; not replacing it", {final_.string()});
    old = final_.parent_path() / ("." + final_.filename().string() + unique_suffix() + ".old");
    fs::rename(final_, old, ec);
    if (ec) throw InputError("cannot move the old output folder aside: " + ec.message(), {final_.string()});
  }
  fs::rename(tmp_, final_, ec);
  if (ec) {
    if (!old.empty()) fs::rename(old, final_);
    throw InputError("cannot move the output folder into place: " + ec.message(), {final_.string()});
  }
  committed_ = true;
  unregister_temporary(slot_);
  slot_ = -1;
  if (!old.empty()) fs::remove_all(old, ec);
}

AtomicFile::AtomicFile(fs::path path, bool overwrite) : path_(std::move(path)) {
  refuse_special_output(path_, OutputKind::file);
  std::error_code ec;
  if (!overwrite && fs::exists(path_, ec)) throw InputError("file exists (use --force to replace it)", {path_.string()});
  if (path_.has_parent_path()) fs::create_directories(path_.parent_path(), ec);
  tmp_ = path_.parent_path() / ("." + path_.filename().string() + unique_suffix());
  slot_ = register_temporary(tmp_);
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd_ < 0) {
    unregister_temporary(slot_);
    throw InputError("cannot write file", {tmp_.string()});
  }
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) {
    ::close(fd_);
    std::error_code ec;
    fs::remove(tmp_, ec);
  }
  if (slot_ >= 0) unregister_temporary(slot_);
}

void AtomicFile::fail(const std::string& message, const fs::path& where) {
  ::close(fd_);
  fd_ = -1;
  std::error_code ec;
  fs::remove(tmp_, ec);
  throw InputError(message, {where.string()});
}

void AtomicFile::append(std::string_view bytes) {
  ROE_CHECK(fd_ >= 0, "AtomicFile: append after commit");
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail("write failed (disk full?)", tmp_);
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}

void AtomicFile::commit() {
  ROE_CHECK(fd_ >= 0, "AtomicFile: committed twice");
  if (::close(fd_) != 0) {
    fd_ = -1;
    std::error_code ec;
    fs::remove(tmp_, ec);
    throw InputError("write failed (disk full?)", {tmp_.string()});
  }
  fd_ = -1;
  std::error_code ec;
  try {
    refuse_special_output(path_, OutputKind::file);  // made since the constructor: still not replaced
  } catch (...) {
    fs::remove(tmp_, ec);
    throw;
  }
  fs::rename(tmp_, path_, ec);
  if (ec) {
    fs::remove(tmp_, ec);
    throw InputError("cannot rename temporary file into place", {path_.string()});
  }
}

void write_file_atomic(const fs::path& path, std::string_view content, bool overwrite) {
  AtomicFile f(path, overwrite);
  f.append(content);
  f.commit();
}

std::string sha256_file(const fs::path& path) {
  const InputFile in(path);
  Sha256 h;
  std::array<char, 1 << 16> buf;
  for (std::uint64_t at = 0; at < in.size();) {
    const std::size_t n = in.read_at(at, buf.data(), buf.size());
    if (n == 0) break;
    h.update(buf.data(), n);
    at += n;
  }
  return h.hex();
}

std::string sha256_hex(std::string_view bytes) {
  Sha256 h;
  h.update(bytes.data(), bytes.size());
  return h.hex();
}

}  // namespace roe::io
