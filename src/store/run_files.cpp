// The run folder's tables: one column table per file, used by its writer and its reader.
#include "roe/store/run_files.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <optional>

#include "roe/io/csv.hpp"
#include "roe/io/output.hpp"
#include "roe/io/trajectory_io.hpp"
#include "roe/math/so3.hpp"

namespace roe::store {

// store reads and writes through io's primitives.
using io::AtomicFile;
using io::CsvHeader;
using io::CsvOptions;
using io::CsvReader;
using io::CsvWriter;
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The current row's field of one column, read with the file's rules.
struct Field {
  const CsvReader& r;
  std::size_t col;
  bool nonfinite;

  double number() const { return nonfinite ? r.get_double_nonfinite(col) : r.get_double(col); }
  /// An empty field, or an optional column the file lacks (col == npos), is nan.
  double number_or_nan() const {
    return col == std::string::npos || r.is_empty(col) ? kNaN : r.get_double_nonfinite(col);
  }
  double sigma() const {
    const double v = number();
    if (v < 0) throw r.error(col, "a standard deviation must not be negative");
    return v;
  }
  /// A σ the writer may leave empty (states.csv at output level "standard": not recorded at that row): nan.
  /// Only the empty cell means that: a written nan is refused, by every reader of the file alike (issue 51).
  double sigma_or_nan() const {
    if (r.is_empty(col)) return kNaN;
    const double v = sigma();
    if (std::isnan(v))
      throw r.error(col, "a written nan standard deviation (roe leaves a σ it did not record empty, never nan)");
    return v;
  }
  std::int64_t int64() const { return r.get_int64(col); }
  int integer() const { return r.get_int(col); }
  std::string text() const { return r.get_string(col); }
  /// An optional column the file lacks (col == npos) is the empty string.
  std::string text_or_empty() const { return col == std::string::npos ? std::string() : r.get_string(col); }
  /// Normalises q after checking it is unit within `tol` (an error at this column: the last one of q).
  /// Always normalised, as the readers did before this table (eval's outputs keep their bytes): a written
  /// quaternion reads back to within an ulp or two.
  void unit(Eigen::Quaterniond& q, double tol) const {
    const double n = q.norm();
    if (!(std::abs(n - 1.0) <= tol)) throw r.error(col, fmt::format("quaternion norm {:.6g} is not 1", n));
    q.normalize();
  }
};

/// One column: its name, how a row W writes it, how it is read into a row R. `k` is the component
/// (axis) the accessors take; `optional` columns may be absent from a file (their reader is then called
/// with Field::col = npos and must give the row its value for "absent").
template <class W, class R>
struct Column {
  using Write = void (*)(CsvWriter&, const W&, int k);
  using Read = void (*)(const Field&, R&, int k);
  std::string name;
  Write write;
  Read read;
  int k = 0;
  bool optional = false;
};
template <class W, class R = W>
using Table = std::vector<Column<W, R>>;

/// prefix + sep + axis for each axis letter, component k = 0, 1, ...
template <class W, class R>
void axes(Table<W, R>& t, const std::string& prefix, const char* letters, typename Column<W, R>::Write write,
          typename Column<W, R>::Read read, const char* sep = "_") {
  for (int k = 0; letters[k] != '\0'; ++k) t.push_back({prefix + sep + letters[k], write, read, k});
}

// Accessor pairs for the tables below: a vector member (component k), a σ vector member from offset `off`
// (ROE_ROW_SIGMA: one a row may leave unrecorded, nan ↔ an empty cell),
// a quaternion member (x y z w, written canonical, checked unit and normalised once w is read).
#define ROE_VEC(m)                                                            \
  [](CsvWriter& w, const auto& r, int k) { w.add(r.m(k)); },                  \
  [](const Field& f, auto& r, int k) { r.m(k) = f.number(); }
#define ROE_SIGMA(m, off)                                                     \
  [](CsvWriter& w, const auto& r, int k) { w.add(r.m((off) + k)); },          \
  [](const Field& f, auto& r, int k) { r.m((off) + k) = f.sigma(); }
#define ROE_ROW_SIGMA(m, off)                                                         \
  [](CsvWriter& w, const auto& r, int k) {                                            \
    const double v = r.m((off) + k);                                                  \
    if (std::isnan(v))                                                                \
      w.add_empty();                                                                  \
    else                                                                              \
      w.add(v);                                                                       \
  },                                                                                  \
  [](const Field& f, auto& r, int k) { r.m((off) + k) = f.sigma_or_nan(); }
#define ROE_QUAT(m)                                                                   \
  [](CsvWriter& w, const auto& r, int k) { w.add(math::canonical(r.m).coeffs()(k)); }, \
  [](const Field& f, auto& r, int k) {                                                \
    r.m.coeffs()(k) = f.number();                                                     \
    if (k == 3) f.unit(r.m, 1e-3);                                                    \
  }

template <class W, class R>
Column<W, R> stamp_column() {
  return {"timestamp_ns", [](CsvWriter& w, const W& r, int) { w.add(r.t_ns); },
          [](const Field& f, R& r, int) { r.t_ns = f.int64(); }};
}

// states.csv
const Table<RecordedState>& states_table() {
  static const Table<RecordedState> t = [] {
    Table<RecordedState> t{stamp_column<RecordedState, RecordedState>()};
    axes(t, "p_W_I", "xyz", ROE_VEC(x.p_W_I));
    axes(t, "v_W_I", "xyz", ROE_VEC(x.v_W_I));
    axes(t, "q_W_I", "xyzw", ROE_QUAT(x.q_W_I));
    axes(t, "b_g", "xyz", ROE_VEC(x.b_g));
    axes(t, "b_a", "xyz", ROE_VEC(x.b_a));
    axes(t, "p_I_C", "xyz", ROE_VEC(T_I_C.p));
    axes(t, "q_I_C", "xyzw", ROE_QUAT(T_I_C.q));
    axes(t, "sigma_p_W_I", "xyz", ROE_ROW_SIGMA(sigma, 0));
    axes(t, "sigma_v_W_I", "xyz", ROE_ROW_SIGMA(sigma, 3));
    axes(t, "sigma_theta_W_I", "xyz", ROE_ROW_SIGMA(sigma, 6));
    axes(t, "sigma_b_g", "xyz", ROE_ROW_SIGMA(sigma, 9));
    axes(t, "sigma_b_a", "xyz", ROE_ROW_SIGMA(sigma, 12));
    axes(t, "sigma_p_I_C", "xyz", ROE_ROW_SIGMA(sigma, 15));
    axes(t, "sigma_theta_I_C", "xyz", ROE_ROW_SIGMA(sigma, 18));
    // The time offset (issue 49): optional, files written before it lack both columns (nan).
    t.push_back({"time_offset_s", [](CsvWriter& w, const RecordedState& r, int) { w.add(r.time_offset_s); },
                 [](const Field& f, RecordedState& r, int) { r.time_offset_s = f.number_or_nan(); }, 0, true});
    t.push_back({"sigma_time_offset_s",
                 [](CsvWriter& w, const RecordedState& r, int) {
                   if (std::isnan(r.sigma_time_offset_s))
                     w.add_empty();
                   else
                     w.add(r.sigma_time_offset_s);
                 },
                 [](const Field& f, RecordedState& r, int) {
                   r.sigma_time_offset_s = f.col == std::string::npos ? kNaN : f.sigma_or_nan();
                 },
                 0, true});
    return t;
  }();
  return t;
}

// objects.csv
const Table<ObjectRow>& objects_table() {
  static const Table<ObjectRow> t = [] {
    Table<ObjectRow> t{stamp_column<ObjectRow, ObjectRow>()};
    t.push_back({"object_id", [](CsvWriter& w, const ObjectRow& r, int) { w.add(r.object_id); },
                 [](const Field& f, ObjectRow& r, int) { r.object_id = f.integer(); }});
    t.push_back({"anchor", [](CsvWriter& w, const ObjectRow& r, int) { w.add(r.anchor ? 1 : 0); },
                 [](const Field& f, ObjectRow& r, int) {
                   const int a = f.integer();
                   if (a != 0 && a != 1) throw f.r.error(f.col, "expected 0 or 1");
                   r.anchor = a == 1;
                 }});
    axes(t, "p_O_W", "xyz", ROE_VEC(T_O_W.p));
    axes(t, "q_O_W", "xyzw", ROE_QUAT(T_O_W.q));
    axes(t, "sigma_p", "xyz", ROE_SIGMA(sigma, 0));
    axes(t, "sigma_theta", "xyz", ROE_SIGMA(sigma, 3));
    axes(t, "sigma_p_W_O", "xyz", ROE_SIGMA(sigma_W_O, 0));
    axes(t, "sigma_theta_W_O", "xyz", ROE_SIGMA(sigma_W_O, 3));
    axes(t, "sigma_p_A_O", "xyz", ROE_SIGMA(sigma_A_O, 0));
    axes(t, "sigma_theta_A_O", "xyz", ROE_SIGMA(sigma_A_O, 3));
    return t;
  }();
  return t;
}

// reprojection.csv: written from the filter's outcome, read as eval's DetectionPose. The pose is nan
// (written) / empty or nan (read) for a detection whose object has no object-world yet.
using RepColumn = Column<ReprojectionRow, eval::DetectionPose>;
const Table<ReprojectionRow, eval::DetectionPose>& reprojection_table() {
  static const Table<ReprojectionRow, eval::DetectionPose> t = [] {
    Table<ReprojectionRow, eval::DetectionPose> t{stamp_column<ReprojectionRow, eval::DetectionPose>()};
    t.push_back({"object_id", [](CsvWriter& w, const ReprojectionRow& r, int) { w.add(r.object_id); },
                 [](const Field& f, eval::DetectionPose& r, int) { r.object_id = f.integer(); }});
    const RepColumn::Write pos = [](CsvWriter& w, const ReprojectionRow& r, int k) {
      w.add(r.outcome.has_T_W_I ? r.outcome.T_W_I.p(k) : kNaN);
    };
    const RepColumn::Read read_pos = [](const Field& f, eval::DetectionPose& r, int k) {
      r.T_W_I.p(k) = f.number_or_nan();
    };
    const RepColumn::Write rot = [](CsvWriter& w, const ReprojectionRow& r, int k) {
      w.add(r.outcome.has_T_W_I ? math::canonical(r.outcome.T_W_I.q).coeffs()(k) : kNaN);
    };
    const RepColumn::Read read_rot = [](const Field& f, eval::DetectionPose& r, int k) {
      r.T_W_I.q.coeffs()(k) = f.number_or_nan();
      if (k != 3) return;
      if (r.T_W_I.p.allFinite() && r.T_W_I.q.coeffs().allFinite()) {
        f.unit(r.T_W_I.q, 0.05);
      } else {  // kept for the status counts, with a nan position
        r.T_W_I = Pose();
        r.T_W_I.p.setConstant(kNaN);
      }
    };
    axes(t, "t", "xyz", pos, read_pos, "");
    axes(t, "q", "xyzw", rot, read_rot, "");
    t.push_back({"status", [](CsvWriter& w, const ReprojectionRow& r, int) { w.add(ekf::to_string(r.outcome.status)); },
                 [](const Field& f, eval::DetectionPose& r, int) { r.status = f.text(); }});
    t.push_back({"nis", [](CsvWriter& w, const ReprojectionRow& r, int) { w.add(r.outcome.nis); },
                 [](const Field& f, eval::DetectionPose& r, int) { r.nis = f.number_or_nan(); }, 0, true});
    // Which part of the detection updated the filter (gate_mode split, symmetric objects); optional.
    t.push_back({"used", [](CsvWriter& w, const ReprojectionRow& r, int) { w.add(ekf::to_string(r.outcome.used)); },
                 [](const Field& f, eval::DetectionPose& r, int) { r.used = f.text_or_empty(); }, 0, true});
    return t;
  }();
  return t;
}

// The table a row type is written with (RunFileWriter).
const Table<RecordedState>& table_of(const RecordedState*) { return states_table(); }
const Table<ObjectRow>& table_of(const ObjectRow*) { return objects_table(); }
const Table<ReprojectionRow, eval::DetectionPose>& table_of(const ReprojectionRow*) { return reprojection_table(); }

#undef ROE_VEC
#undef ROE_SIGMA
#undef ROE_ROW_SIGMA
#undef ROE_QUAT

template <class W, class R>
std::vector<std::string> names(const Table<W, R>& t) {
  std::vector<std::string> n;
  n.reserve(t.size());
  for (const auto& c : t) n.push_back(c.name);
  return n;
}

/// One row of table `t` into `w`.
template <class W, class R>
void add_row(const Table<W, R>& t, CsvWriter& w, const W& row) {
  for (const auto& c : t) c.write(w, row, c.k);
  w.end_row();
}

/// The table's text: header and rows.
template <class W, class R>
CsvWriter fill_table(const Table<W, R>& t, const std::vector<W>& rows) {
  CsvWriter w;
  w.header(names(t));
  for (const W& row : rows) add_row(t, w, row);
  return w;
}

/// Reads the listed columns (empty: all) of table `t` from `file`, calling sink(row) for each data row;
/// false with *missing set when a listed column is absent and `missing` is given.
template <class W, class R, class Sink>
bool read_table(const Table<W, R>& t, const fs::path& file, const RunFileRead& read, std::string* missing,
                Sink&& sink) {
  CsvOptions o;
  o.header = CsvHeader::kFirstLine;
  o.allow_nonfinite = read.allow_nonfinite;
  CsvReader r(file, o);
  // (table entry, file column) of every column read, in table order; npos for an absent optional one.
  std::vector<std::pair<const Column<W, R>*, std::size_t>> cols;
  for (const std::string& name : read.columns)
    ROE_CHECK(std::any_of(t.begin(), t.end(), [&](const Column<W, R>& c) { return c.name == name; }),
              "run file reader: unknown column " + name);
  for (const auto& c : t) {
    if (!read.columns.empty() && std::find(read.columns.begin(), read.columns.end(), c.name) == read.columns.end())
      continue;
    if (const auto i = r.find_column(c.name)) {
      cols.emplace_back(&c, *i);
    } else if (c.optional) {
      cols.emplace_back(&c, std::string::npos);
    } else if (missing != nullptr) {
      *missing = fmt::format("{} has no {} column", file.filename().string(), c.name);
      return false;
    } else {
      r.column(c.name);  // the located error naming it
    }
  }
  ROE_CHECK(!cols.empty() && cols.front().first->name == "timestamp_ns", "run file reader: the stamp is read first");
  Timestamp last = std::numeric_limits<Timestamp>::min();
  while (r.next()) {
    R row;
    for (const auto& [c, i] : cols) c->read(Field{r, i, read.allow_nonfinite}, row, c->k);
    if (row.t_ns < last)
      throw r.error(cols.front().second, fmt::format("time stamps must not decrease ({} after {})", row.t_ns, last));
    last = row.t_ns;
    sink(std::move(row));
  }
  return true;
}

template <class W, class R>
std::vector<R> read_all(const Table<W, R>& t, const fs::path& file, const RunFileRead& read) {
  std::vector<R> rows;
  read_table(t, file, read, nullptr, [&](R&& row) { rows.push_back(std::move(row)); });
  return rows;
}

}  // namespace

const std::vector<std::string>& states_csv_columns() {
  static const std::vector<std::string> n = names(states_table());
  return n;
}
const std::vector<std::string>& objects_csv_columns() {
  static const std::vector<std::string> n = names(objects_table());
  return n;
}
const std::vector<std::string>& reprojection_csv_columns() {
  static const std::vector<std::string> n = names(reprojection_table());
  return n;
}

std::string format_states_csv(const std::vector<RecordedState>& rows) { return fill_table(states_table(), rows).str(); }
std::string format_objects_csv(const std::vector<ObjectRow>& rows) { return fill_table(objects_table(), rows).str(); }
std::string format_reprojection_csv(const std::vector<ReprojectionRow>& rows) {
  return fill_table(reprojection_table(), rows).str();
}
template <class Row>
struct RunFileWriter<Row>::Impl {
  explicit Impl(const fs::path& file) : f(file) { w.header(names(table_of(static_cast<const Row*>(nullptr)))); }
  AtomicFile f;
  CsvWriter w;
};

template <class Row>
RunFileWriter<Row>::RunFileWriter(const fs::path& file) : impl_(std::make_unique<Impl>(file)) {}
template <class Row>
RunFileWriter<Row>::~RunFileWriter() = default;
template <class Row>
void RunFileWriter<Row>::add(const Row& row) {
  add_row(table_of(static_cast<const Row*>(nullptr)), impl_->w, row);
  impl_->w.flush_to(impl_->f, CsvWriter::kFlushBytes);
}
template <class Row>
void RunFileWriter<Row>::commit() {
  impl_->w.flush_to(impl_->f);
  impl_->f.commit();
}
template class RunFileWriter<RecordedState>;
template class RunFileWriter<ObjectRow>;
template class RunFileWriter<ReprojectionRow>;

namespace {
template <class Row>
void write_rows(const fs::path& file, const std::vector<Row>& rows) {
  RunFileWriter<Row> w(file);
  for (const Row& row : rows) w.add(row);
  w.commit();
}
}  // namespace

void write_states_csv(const fs::path& file, const std::vector<RecordedState>& rows) { write_rows(file, rows); }
void write_objects_csv(const fs::path& file, const std::vector<ObjectRow>& rows) { write_rows(file, rows); }
void write_reprojection_csv(const fs::path& file, const std::vector<ReprojectionRow>& rows) { write_rows(file, rows); }

RunFolderWriter::RunFolderWriter(const RunConfig& config, const std::function<fs::path(const std::string&)>& path_of,
                                 const RunFolderRows& rows)
    : rows_(rows) {
  const auto has = [&](const std::string& file) { return run_folder_has(config, file); };
  const std::string states = "states" + rows.states_suffix + ".csv", trajectory = "trajectory" + rows.states_suffix;
  if (rows.states && has(states)) states_.emplace(path_of(states));
  if (rows.objects && has("objects.csv")) objects_.emplace(path_of("objects.csv"));
  if (rows.objects && has("reprojection.csv")) reprojection_.emplace(path_of("reprojection.csv"));
  for (const auto& [ext, format] :
       {std::pair{".csv", io::TrajectoryFormat::kCsv}, std::pair{".tum", io::TrajectoryFormat::kTum}})
    if (rows.states && has(trajectory + ext))
      trajectories_.push_back(std::make_unique<io::TrajectoryWriter>(path_of(trajectory + ext), format));
}
RunFolderWriter::~RunFolderWriter() = default;

void RunFolderWriter::state(const RecordedState& row) {
  ROE_CHECK(rows_.states, "RunFolderWriter: a state row for a writer of other rows");
  if (states_) states_->add(row);
  for (const auto& t : trajectories_) t->add(StampedPose{row.t_ns, Pose(row.x.q_W_I, row.x.p_W_I)});
}
void RunFolderWriter::object(const ObjectRow& row) {
  ROE_CHECK(rows_.objects, "RunFolderWriter: an object row for a writer of other rows");
  if (objects_) objects_->add(row);
}
void RunFolderWriter::reprojection(const ReprojectionRow& row) {
  ROE_CHECK(rows_.objects, "RunFolderWriter: a reprojection row for a writer of other rows");
  if (reprojection_) reprojection_->add(row);
}
void RunFolderWriter::commit() {
  if (states_) states_->commit();
  if (objects_) objects_->commit();
  if (reprojection_) reprojection_->commit();
  for (const auto& t : trajectories_) t->commit();
}

namespace {

// One state row in the spill file: the stamp's bits, then the doubles of every field the files hold.
constexpr std::size_t kSpillDoubles = 47;
using SpillRecord = std::array<double, kSpillDoubles>;

template <class V>
double* put(double* d, const V& v) {
  for (Eigen::Index i = 0; i < v.size(); ++i) *d++ = v(i);
  return d;
}
template <class V>
const double* get(const double* d, V& v) {
  for (Eigen::Index i = 0; i < v.size(); ++i) v(i) = *d++;
  return d;
}

void to_record(const RecordedState& r, SpillRecord& rec) {
  std::memcpy(rec.data(), &r.t_ns, sizeof(double));
  double* d = rec.data() + 1;
  for (const Eigen::Vector3d* v : {&r.x.p_W_I, &r.x.v_W_I}) d = put(d, *v);
  d = put(d, r.x.q_W_I.coeffs());
  for (const Eigen::Vector3d* v : {&r.x.b_g, &r.x.b_a, &r.T_I_C.p}) d = put(d, *v);
  d = put(d, r.T_I_C.q.coeffs());
  d = put(d, r.sigma);
  *d++ = r.time_offset_s;
  *d++ = r.sigma_time_offset_s;
  ROE_CHECK(d == rec.data() + kSpillDoubles, "SpilledStateRows: the record's layout");
}

void from_record(const SpillRecord& rec, RecordedState& r) {
  std::memcpy(&r.t_ns, rec.data(), sizeof(double));
  const double* d = rec.data() + 1;
  for (Eigen::Vector3d* v : {&r.x.p_W_I, &r.x.v_W_I}) d = get(d, *v);
  d = get(d, r.x.q_W_I.coeffs());
  for (Eigen::Vector3d* v : {&r.x.b_g, &r.x.b_a, &r.T_I_C.p}) d = get(d, *v);
  d = get(d, r.T_I_C.q.coeffs());
  d = get(d, r.sigma);
  r.time_offset_s = *d++;
  r.sigma_time_offset_s = *d++;
  r.pose_cov.setZero();
}

}  // namespace

namespace {

/// A temporary file written at its end and read anywhere (pwrite/pread), removed with the object and, while it
/// lives, on SIGINT/SIGTERM/SIGHUP. `what` names its content in the error of a failed write or read.
class TemporaryFile {
 public:
  TemporaryFile(const fs::path& file, const char* what) : file_(file), what_(what), cleanup_(file) {
    fd_ = ::open(file.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd_ < 0) fail("create");
  }
  ~TemporaryFile() {
    ::close(fd_);
    std::error_code ec;
    fs::remove(file_, ec);  // path-checked: a hidden name roe made in the run's own temporary folder, never read from input
  }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  std::uint64_t append(const void* data, std::size_t n) {
    const std::uint64_t at = size_;
    for (const char* p = static_cast<const char*>(data); n > 0;) {
      const ssize_t k = ::pwrite(fd_, p, n, static_cast<off_t>(size_));
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) fail("write");
      p += k;
      n -= static_cast<std::size_t>(k);
      size_ += static_cast<std::uint64_t>(k);
    }
    return at;
  }
  void read(std::uint64_t offset, void* data, std::size_t n) const {
    ROE_CHECK(offset + n <= size_, "temporary file: a read beyond what was written");
    for (char* p = static_cast<char*>(data); n > 0;) {
      const ssize_t k = ::pread(fd_, p, n, static_cast<off_t>(offset));
      if (k < 0 && errno == EINTR) continue;
      if (k <= 0) fail("read");
      p += k;
      n -= static_cast<std::size_t>(k);
      offset += static_cast<std::uint64_t>(k);
    }
  }
  std::uint64_t size() const { return size_; }

 private:
  [[noreturn]] void fail(const char* op) const {
    throw InputError(fmt::format("cannot {} the temporary file of {} ({})", op, what_, std::strerror(errno)),
                     {file_.string()});
  }
  fs::path file_;
  const char* what_;
  io::SignalCleanup cleanup_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
};

}  // namespace

struct SpilledStateRows::Impl {
  explicit Impl(const fs::path& p) : file(p, "the smoothed rows") {}
  TemporaryFile file;
  std::vector<std::pair<std::uint64_t, std::size_t>> blocks;  // (offset, rows), in the order given
  std::uint64_t rows = 0;
  std::vector<SpillRecord> buf;
};

SpilledStateRows::SpilledStateRows(const fs::path& file) : impl_(std::make_unique<Impl>(file)) {}
SpilledStateRows::~SpilledStateRows() = default;

void SpilledStateRows::block(const std::vector<RecordedState>& rows) {
  if (rows.empty()) return;
  Impl& m = *impl_;
  m.buf.resize(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) to_record(rows[i], m.buf[i]);
  m.blocks.emplace_back(m.file.append(m.buf.data(), rows.size() * sizeof(SpillRecord)), rows.size());
  m.rows += rows.size();
}

void SpilledStateRows::replay(RunRowSink& sink) {
  Impl& m = *impl_;
  RecordedState row;
  for (auto b = m.blocks.rbegin(); b != m.blocks.rend(); ++b) {
    m.buf.resize(b->second);
    m.file.read(b->first, m.buf.data(), b->second * sizeof(SpillRecord));
    for (const SpillRecord& rec : m.buf) {
      from_record(rec, row);
      sink.state(row);
    }
  }
}

struct RecordingFile::Impl {
  explicit Impl(const fs::path& p) : file(p, "the filter's recording") {}
  TemporaryFile file;
};

RecordingFile::RecordingFile(const fs::path& file) : impl_(std::make_unique<Impl>(file)) {}
RecordingFile::~RecordingFile() = default;
std::uint64_t RecordingFile::append(const void* data, std::size_t n) { return impl_->file.append(data, n); }
void RecordingFile::read(std::uint64_t offset, void* data, std::size_t n) const { impl_->file.read(offset, data, n); }
std::uint64_t RecordingFile::size() const { return impl_->file.size(); }

std::size_t SpilledStateRows::rows() const { return impl_->rows; }

std::vector<RecordedState> read_states_csv(const fs::path& file, const RunFileRead& read) {
  return read_all(states_table(), file, read);
}

bool for_each_state_row(const fs::path& file, const RunFileRead& read,
                        const std::function<void(const RecordedState&)>& fn, std::string* missing) {
  return read_table(states_table(), file, read, missing, [&](RecordedState&& row) { fn(row); });
}

std::vector<ObjectRow> read_objects_csv(const fs::path& file) { return read_all(objects_table(), file, {}); }

std::vector<eval::DetectionPose> read_reprojection_csv(const fs::path& file) {
  RunFileRead read;
  read.allow_nonfinite = true;
  return read_all(reprojection_table(), file, read);
}

void check_reprojection_rows(const std::vector<eval::DetectionPose>& rows,
                             const std::vector<ekf::ImageDetections>& images, const fs::path& file) {
  std::map<std::pair<Timestamp, int>, long> balance;  // detections minus rows, per (time, object)
  std::size_t n_detections = 0;
  for (const auto& im : images)
    for (const auto& d : im.detections) {
      ++balance[{im.t_ns, d.object_id}];
      ++n_detections;
    }
  for (const auto& r : rows) --balance[{r.t_ns, r.object_id}];
  std::optional<std::pair<Timestamp, int>> no_row, no_det;
  std::size_t n_no_row = 0, n_no_det = 0;
  for (const auto& [k, n] : balance) {
    if (n > 0 && n_no_row++ == 0) no_row = k;
    if (n < 0 && n_no_det++ == 0) no_det = k;
  }
  if (no_row)
    throw InputError(fmt::format("no row for {} of the run's {} detections (first: object {} at {} ns, {:.6f} s): "
                                 "not the reprojection.csv of this run and dataset (shifted, truncated, header only "
                                 "or another run's)",
                                 n_no_row, n_detections, no_row->second, no_row->first, to_seconds(no_row->first)),
                     {file.string()});
  if (no_det)
    throw InputError(fmt::format("{} rows name no detection of the run (first: object {} at {} ns, {:.6f} s): not "
                                 "the reprojection.csv of this run and dataset",
                                 n_no_det, no_det->second, no_det->first, to_seconds(no_det->first)),
                     {file.string()});
}

}  // namespace roe::store
