#pragma once
/// @file
/// Strict CSV (and whitespace-separated) text tables: every malformed row is a roe::InputError
/// carrying the file, the 1-based line and the 1-based column (= field index).
///
/// Reading (row cursor):
///   roe::io::CsvOptions o;
///   o.expected_header = {"timestamp [ns]", "w_RS_S_x [rad s^-1]", ...};   // checked, in order
///   o.stamp_column = 0;                                                  // strictly increasing
///   roe::io::CsvReader r(path, o);
///   while (r.next()) {
///     const Timestamp t = r.get_int64(0);
///     const double wx = r.get_double(1);     // NaN / inf rejected, trailing garbage rejected
///   }
/// Matching columns by name in any order: leave expected_header empty and use
///   const std::size_t c_t = r.column("t");   // InputError naming the missing column
///
/// Writing (into a string, then one atomic write):
///   roe::io::CsvWriter w;
///   w.header({"timestamp [ns]", "filename"}, "#");
///   w.add(t_ns).add(name).end_row();
///   w.write(path);    // write_file_atomic
/// or streamed, for large tables: an AtomicFile f(path), w.flush_to(f, CsvWriter::kFlushBytes) after each
/// row, then w.flush_to(f); f.commit().
///
/// Header conventions: with CsvHeader::kFirstLine, the first non-blank line is the header; a comment
/// prefix at its start is removed (EuRoC: "#timestamp [ns],..."), and each name is trimmed of
/// surrounding spaces (EuRoC ground truth: "#timestamp, p_RS_R_x [m], ..."). Later lines that begin
/// with the comment prefix are skipped; blank lines are skipped everywhere; CRLF and a UTF-8 BOM are
/// accepted.

#include <cstdint>
#include <deque>
#include <system_error>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "roe/core/error.hpp"

namespace roe::io {

class AtomicFile;  // io/output.hpp

namespace fs = std::filesystem;

/// Where the column names come from.
enum class CsvHeader {
  kNone,       ///< no header line; comment lines are skipped
  kFirstLine,  ///< the first non-blank line is the header (a leading comment prefix is removed)
};

/// Required order of the stamp column.
enum class StampOrder { kAny, kNonDecreasing, kStrictlyIncreasing };

/// How the stamp column is parsed for the order check.
enum class StampKind {
  kNanoseconds,  ///< int64 (roe, EuRoC)
  kSeconds,      ///< double (TUM, cnspy)
};

class InputFile;

struct CsvOptions {
  /// Field separator in delimited mode.
  char delimiter = ',';
  /// Split on runs of spaces and tabs instead of `delimiter` (TUM files). No quoting in this mode.
  bool whitespace_delimited = false;
  /// Lines whose first non-blank characters are this prefix are comments. Empty = no comments.
  std::string comment_prefix = "#";
  CsvHeader header = CsvHeader::kFirstLine;
  /// When non-empty, the header must have exactly these names, in this order (after trimming and
  /// removal of the comment prefix). An entry may list accepted spellings separated by '|', e.g.
  /// "timestamp [ns]|timestamp".
  std::vector<std::string> expected_header;
  /// Exact number of fields in every row; 0 = the header's size (or, without a header, the size of
  /// the first data row).
  std::size_t columns = 0;
  /// Accept rows with any number of fields (e.g. Motive exports with sparse columns). get_* on a
  /// missing field is then an error at that column.
  bool ragged = false;
  /// In delimited mode, a field may be quoted ("a,b" with "" for a quote).
  bool quotes = true;
  /// Remove spaces and tabs around each field (delimited mode).
  bool trim = true;
  /// Default for get_double: whether NaN and ±inf are accepted.
  bool allow_nonfinite = false;
  /// 0-based column whose value must follow `stamp_order`; -1 = no check.
  int stamp_column = -1;
  StampKind stamp_kind = StampKind::kNanoseconds;
  StampOrder stamp_order = StampOrder::kStrictlyIncreasing;
};

/// Reads a table row by row. A file is read in chunks of 1 MiB as the rows are consumed (a row longer
/// than a chunk is read whole), so its text is never held at once; a table given as text is held whole.
/// The fields of a row stay valid until the next call of next().
class CsvReader {
 public:
  /// Opens `path` (io::InputFile: a regular file, read up to its size at open time), and parses/checks
  /// the header. InputError when unreadable or bad header.
  CsvReader(const fs::path& path, CsvOptions options = {});
  ~CsvReader();
  /// A table given as text; `source` names it in errors.
  static CsvReader from_text(std::string text, std::string source, CsvOptions options = {});
  // Fields are views into the reader's buffer, so a reader is neither copied nor moved
  // (C++17 guaranteed elision still allows `auto r = CsvReader::from_text(...)`).
  CsvReader(const CsvReader&) = delete;
  CsvReader(CsvReader&&) = delete;
  CsvReader& operator=(const CsvReader&) = delete;
  CsvReader& operator=(CsvReader&&) = delete;

  /// The header's names (trimmed, comment prefix removed); empty when the table has none.
  const std::vector<std::string>& header() const { return header_; }
  /// Line number of the header (0 when none).
  std::int64_t header_line() const { return header_line_; }
  /// 0-based index of a header column, if present.
  std::optional<std::size_t> find_column(std::string_view name) const;
  /// 0-based index of a header column; InputError (at the header line) when missing.
  std::size_t column(std::string_view name) const;

  /// Advances to the next data row; false at the end of the table. Checks the column count and
  /// the stamp order (InputError).
  bool next();

  /// Number of fields of the current row.
  std::size_t size() const { return fields_.size(); }
  /// 1-based line number of the current row.
  std::int64_t line() const { return line_; }
  /// Data rows returned by next() so far.
  std::size_t rows() const { return rows_; }
  /// Whether the current row is the file's last line and has no line end (the file may have been cut
  /// inside it). next() warns about such a row (log::warn, with file and line) unless options.ragged:
  /// ragged readers know their layout and judge a short last row themselves (Motive drops it).
  bool row_unterminated() const { return unterminated_; }
  const std::string& source() const { return source_; }

  /// The raw (trimmed, unquoted) text of field i (0-based); InputError when the row has no field i.
  std::string_view field(std::size_t i) const;
  bool is_empty(std::size_t i) const { return field(i).empty(); }
  std::string get_string(std::size_t i) const { return std::string(field(i)); }
  /// A double (std::from_chars, whole field). Non-finite values only when options.allow_nonfinite.
  double get_double(std::size_t i) const;
  /// A double that may be NaN/inf ("nan", "inf", "-inf").
  double get_double_nonfinite(std::size_t i) const;
  /// A double, or NaN when the field is empty.
  double get_double_or_nan(std::size_t i) const;
  /// A base-10 int64 (no fraction, no exponent).
  std::int64_t get_int64(std::size_t i) const;
  /// A base-10 int that fits in int.
  int get_int(std::size_t i) const;
  /// Seconds written in decimal ("1305031102.160407", "1.403715529112143517e+09") converted to
  /// integer nanoseconds exactly from the digits (no double rounding; beyond 9 decimals rounded
  /// half away from zero). For the stamps of TUM / cnspy files.
  std::int64_t get_seconds_ns(std::size_t i) const;

  /// An InputError located at the current row and 0-based field `i` (reported 1-based); for
  /// callers' own checks, e.g. `throw r.error(3, "quaternion is not unit norm")`.
  InputError error(std::size_t i, const std::string& message) const;
  /// An InputError located at the current row, without a column.
  InputError row_error(const std::string& message) const;

  /// A field's number as std::from_chars read it while the row was split (value and error code).
  struct Number {
    double value = 0.0;
    std::errc ec{};
    bool parsed = false;  ///< false: the field was not read as a number while splitting
  };

 private:
  CsvReader(std::string text, std::string source, CsvOptions options, std::unique_ptr<InputFile> file);
  bool next_line(std::string_view& line);
  bool refill();
  bool is_blank_or_comment(std::string_view line) const;
  void split(std::string_view line, std::int64_t line_no, std::vector<std::string_view>& out,
             std::vector<Number>* numbers);
  void read_header();
  double parse_double(std::size_t i, bool allow_nonfinite) const;

  std::string text_;                 ///< the text, or the file's bytes from the current line on
  std::unique_ptr<InputFile> file_;  ///< the file text_ is refilled from (null for a table given as text)
  std::uint64_t file_pos_ = 0;       ///< next byte of the file to read
  std::string source_;
  CsvOptions opt_;
  std::size_t pos_ = 0;
  bool unterminated_ = false;
  std::int64_t next_line_no_ = 1;
  std::int64_t line_ = 0;
  std::int64_t header_line_ = 0;
  std::size_t rows_ = 0;
  std::size_t columns_ = 0;
  std::vector<std::string> header_;
  std::vector<std::string_view> fields_;
  std::vector<Number> numbers_;  ///< per field: its number, when parsed while splitting
  mutable std::vector<char> numeric_;           ///< per column: read as a number in some row
  std::deque<std::string> unquoted_;  // storage of fields that needed unescaping (stable addresses)
  bool have_prev_stamp_ = false;
  std::int64_t prev_ns_ = 0;
  double prev_s_ = 0.0;
  std::int64_t prev_stamp_line_ = 0;
};

/// Builds a table in memory. Doubles are written in the shortest form that reads back to the same
/// value (fmt's round-trip representation), so write → read is exact and output is deterministic.
class CsvWriter {
 public:
  /// `delimiter` separates fields (' ' for TUM files).
  explicit CsvWriter(char delimiter = ',');

  /// A comment line: prefix + text.
  CsvWriter& comment(std::string_view text, std::string_view prefix = "#");
  /// The header line (prefix + names joined by the delimiter). Later rows must have as many fields.
  CsvWriter& header(const std::vector<std::string>& names, std::string_view prefix = "");

  CsvWriter& add(double v);  ///< shortest round-trip form; NaN → "nan", ±inf → "inf"/"-inf"
  CsvWriter& add(std::int64_t v);
  CsvWriter& add(int v);
  CsvWriter& add(std::string_view s);  ///< quoted when it contains the delimiter, a quote or a newline
  CsvWriter& add(const char* s) { return add(std::string_view(s)); }
  CsvWriter& add(const std::string& s) { return add(std::string_view(s)); }
  /// Fixed notation with `decimals` digits after the point.
  CsvWriter& add_fixed(double v, int decimals);
  /// A nanosecond stamp as seconds with exactly 9 decimals, from the integer ("1403715523.912140000"):
  /// exact, unlike add_fixed(to_seconds(t), 9) whose double cannot hold epoch nanoseconds.
  CsvWriter& add_seconds(std::int64_t t_ns);
  CsvWriter& add_empty();
  /// Ends the row; InternalError if the field count differs from the header's.
  CsvWriter& end_row();

  const std::string& str() const { return out_; }
  std::size_t rows() const { return rows_; }
  /// write_file_atomic(file, str(), overwrite).
  void write(const fs::path& file, bool overwrite = true) const;
  /// Streaming a table of any size: when the text built so far holds at least `min_bytes`, appends it to
  /// `file` and empties it (the header's field count is still checked on later rows). Call between rows;
  /// flush_to(file) then file.commit() at the end.
  void flush_to(AtomicFile& file, std::size_t min_bytes = 0);
  /// The piece size the streaming writers of roe's tables use.
  static constexpr std::size_t kFlushBytes = std::size_t{1} << 20;

 private:
  void sep();
  char delim_;
  std::string out_;
  std::size_t header_cols_ = 0;
  std::size_t row_fields_ = 0;
  std::size_t rows_ = 0;
};

/// Shortest round-trip text of a double (as CsvWriter writes it).
std::string format_double(double v);
/// Decimal seconds text → integer nanoseconds, exactly (see CsvReader::get_seconds_ns); nullopt when
/// the text is not a finite decimal number or the result does not fit in int64.
std::optional<std::int64_t> parse_seconds_ns(std::string_view text);
/// Integer nanoseconds → "S.NNNNNNNNN" (exact; "-0.500000000" for −5e8).
std::string format_seconds_ns(std::int64_t t_ns);

}  // namespace roe::io
