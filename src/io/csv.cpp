#include "roe/io/csv.hpp"

#include <fmt/compile.h>
#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <climits>
#include <cmath>
#include <iterator>
#include <limits>

#include "roe/core/log.hpp"
#include "roe/io/input.hpp"
#include "roe/io/output.hpp"

namespace roe::io {
namespace {

bool is_space(char c) { return c == ' ' || c == '\t'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// Quotes a field for display in an error message, shortened when long.
std::string shown(std::string_view s) {
  if (s.size() > 40) return "'" + std::string(s.substr(0, 37)) + "...'";
  return "'" + std::string(s) + "'";
}

// Splits "a|b|c" into its alternatives.
std::vector<std::string_view> alternatives(std::string_view spec) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t bar = spec.find('|', start);
    out.push_back(spec.substr(start, bar == std::string_view::npos ? std::string_view::npos : bar - start));
    if (bar == std::string_view::npos) break;
    start = bar + 1;
  }
  return out;
}

}  // namespace

// -------------------------------------------------------------------------------------------------
// CsvReader
// -------------------------------------------------------------------------------------------------

CsvReader::CsvReader(const fs::path& path, CsvOptions options)
    : CsvReader(std::string(), path.string(), std::move(options), std::make_unique<InputFile>(path)) {}

CsvReader::~CsvReader() = default;

CsvReader CsvReader::from_text(std::string text, std::string source, CsvOptions options) {
  return CsvReader(std::move(text), std::move(source), std::move(options), nullptr);
}

CsvReader::CsvReader(std::string text, std::string source, CsvOptions options, std::unique_ptr<InputFile> file)
    : text_(std::move(text)), file_(std::move(file)), source_(std::move(source)), opt_(std::move(options)) {
  refill();
  // UTF-8 byte order mark (spreadsheet exports).
  pos_ = utf8_bom_length(text_);
  if (!opt_.whitespace_delimited &&
      (opt_.delimiter == '\n' || opt_.delimiter == '\r' || opt_.delimiter == '"'))
    throw InternalError("CsvReader: invalid delimiter");
  columns_ = opt_.columns;
  if (opt_.header == CsvHeader::kFirstLine) read_header();
}

namespace {
/// Bytes read from a file at a time: large enough that the system calls cost nothing, small enough to
/// stay in the cache while the rows are parsed.
constexpr std::size_t kReadChunk = std::size_t{1} << 20;
}  // namespace

/// Drops the consumed text and appends the file's next chunk; false at the end of the file (or of the
/// text given whole). A file that shrank while read ends where its bytes end.
bool CsvReader::refill() {
  if (!file_ || file_pos_ >= file_->size()) return false;
  text_.erase(0, pos_);
  pos_ = 0;
  const std::size_t have = text_.size();
  const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(kReadChunk, file_->size() - file_pos_));
  text_.resize(have + want);
  const std::size_t got = file_->read_at(file_pos_, text_.data() + have, want);
  text_.resize(have + got);
  file_pos_ = got == 0 ? file_->size() : file_pos_ + got;
  return got > 0;
}

bool CsvReader::next_line(std::string_view& line) {
  if (pos_ >= text_.size() && !refill()) return false;
  std::size_t nl = text_.find('\n', pos_);
  while (nl == std::string::npos) {  // the line goes on in the file's next chunk
    const std::size_t scanned = text_.size() - pos_;
    if (!refill()) break;
    nl = text_.find('\n', pos_ + scanned);
  }
  const std::size_t end = nl == std::string::npos ? text_.size() : nl;
  line = std::string_view(text_).substr(pos_, end - pos_);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos_ = nl == std::string::npos ? text_.size() : nl + 1;
  unterminated_ = nl == std::string::npos;
  line_ = next_line_no_++;
  return true;
}

bool CsvReader::is_blank_or_comment(std::string_view line) const {
  std::string_view t = trim(line);
  if (t.empty()) return true;
  return !opt_.comment_prefix.empty() && t.substr(0, opt_.comment_prefix.size()) == opt_.comment_prefix;
}

/// Parses the number that starts at line[at] into `n` (value and error code) and sets `end` after it;
/// true when it ends where its field ends: at the line's end or at a character for which `field_end` is
/// true. The text a field's parse (parse_double) sees then ends right there too, so it would get the same
/// value and error code. (The result is written in place: a Number returned by value and copied into
/// the row's vector cost a store-forwarding stall per field.)
template <typename FieldEnd>
bool number_at(std::string_view line, std::size_t at, FieldEnd field_end, std::size_t& end, CsvReader::Number& n) {
  const char* first = line.data() + at;
  const char* last = line.data() + line.size();
  if (first == last || *first == '+') return false;  // parse_double's own handling of '+'
  const auto r = std::from_chars(first, last, n.value, std::chars_format::general);
  if (r.ec == std::errc::invalid_argument) return false;
  end = static_cast<std::size_t>(r.ptr - line.data());
  if (r.ptr != last && !field_end(*r.ptr)) return false;
  n.ec = r.ec;
  return true;
}

void CsvReader::split(std::string_view line, std::int64_t line_no, std::vector<std::string_view>& out,
                      std::vector<Number>* numbers) {
  out.clear();
  if (numbers) numbers->clear();
  // The number of each field read as a number in an earlier row (numbers != null) is parsed where the
  // field is found: the parse finds the field's end, which spares a second pass over its characters.
  // Other fields (never read as numbers, or not numbers) are split as text.
  const auto numeric = [&] { return numbers && out.size() < numeric_.size() && numeric_[out.size()]; };
  if (opt_.whitespace_delimited) {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && is_space(line[i])) ++i;
      if (i >= line.size()) break;
      const std::size_t start = i;
      const bool as_number = numeric();
      Number* n = numbers ? &numbers->emplace_back() : nullptr;
      if (as_number) n->parsed = number_at(line, start, is_space, i, *n);
      if (!n || !n->parsed)
        for (i = start; i < line.size() && !is_space(line[i]);) ++i;
      out.emplace_back(line.data() + start, i - start);
    }
    return;
  }
  const char d = opt_.delimiter;
  std::size_t i = 0;
  while (true) {
    // One field starting at i.
    std::size_t j = i, k = i;  // k: the first character that is not a space
    if (opt_.trim || opt_.quotes) {
      while (k < line.size() && is_space(line[k]) && line[k] != d) ++k;
      if (opt_.quotes && k < line.size() && line[k] == '"') j = k;
    }
    if (opt_.quotes && j < line.size() && line[j] == '"') {
      std::string value;
      std::size_t k = j + 1;
      bool closed = false;
      while (k < line.size()) {
        if (line[k] == '"') {
          if (k + 1 < line.size() && line[k + 1] == '"') {
            value += '"';
            k += 2;
            continue;
          }
          closed = true;
          ++k;
          break;
        }
        value += line[k++];
      }
      if (!closed)
        throw InputError("unterminated quoted field",
                         {source_, line_no, static_cast<std::int64_t>(out.size() + 1)});
      while (k < line.size() && is_space(line[k]) && line[k] != d) ++k;
      if (k < line.size() && line[k] != d)
        throw InputError("unexpected character after a closing quote",
                         {source_, line_no, static_cast<std::int64_t>(out.size() + 1)});
      unquoted_.push_back(std::move(value));
      out.push_back(unquoted_.back());
      if (numbers) numbers->emplace_back();
      if (k >= line.size()) return;
      i = k + 1;
      continue;
    }
    if (numeric()) {  // a number, then (trimmed) spaces, then the delimiter or the line's end
      const std::size_t start = opt_.trim ? k : i;
      std::size_t stop = 0;
      Number& n = numbers->emplace_back();
      const bool ok = number_at(
          line, start, [&](char c) { return c == d || (opt_.trim && is_space(c)); }, stop, n);
      std::size_t q = stop;
      if (ok && opt_.trim)
        while (q < line.size() && is_space(line[q]) && line[q] != d) ++q;
      if (ok && (q == line.size() || line[q] == d)) {
        n.parsed = true;
        out.emplace_back(line.data() + start, stop - start);
        if (q == line.size()) return;
        i = q + 1;
        continue;
      }
      numbers->pop_back();  // split as text below
    }
    if (numbers) numbers->emplace_back();
    const std::size_t end = line.find(d, i);
    std::string_view f = line.substr(i, end == std::string_view::npos ? std::string_view::npos : end - i);
    out.push_back(opt_.trim ? trim(f) : f);
    if (end == std::string_view::npos) return;
    i = end + 1;
  }
}

void CsvReader::read_header() {
  std::string_view line;
  while (next_line(line)) {
    if (trim(line).empty()) continue;
    std::string_view t = line;
    while (!t.empty() && is_space(t.front())) t.remove_prefix(1);
    if (!opt_.comment_prefix.empty() && t.substr(0, opt_.comment_prefix.size()) == opt_.comment_prefix)
      t.remove_prefix(opt_.comment_prefix.size());
    header_line_ = line_;
    std::vector<std::string_view> names;
    unquoted_.clear();
    split(t, line_, names, nullptr);
    header_.assign(names.begin(), names.end());
    break;
  }
  if (header_line_ == 0) throw InputError("empty file: missing header line", {source_, 1, 0});
  if (!opt_.expected_header.empty()) {
    const auto& exp = opt_.expected_header;
    const std::size_t n = std::min(exp.size(), header_.size());
    for (std::size_t c = 0; c < n; ++c) {
      bool ok = false;
      for (auto alt : alternatives(exp[c])) ok = ok || alt == header_[c];
      if (!ok) {
        std::string want;
        for (auto alt : alternatives(exp[c])) want += (want.empty() ? "" : " or ") + shown(alt);
        throw InputError("unexpected header: column is " + shown(header_[c]) + ", expected " + want,
                         {source_, header_line_, static_cast<std::int64_t>(c + 1)});
      }
    }
    if (header_.size() != exp.size()) {
      const std::size_t c = n;  // first missing or first extra column
      throw InputError(
          fmt::format("unexpected header: {} columns, expected {}{}", header_.size(), exp.size(),
                      header_.size() < exp.size() ? " (missing " + shown(alternatives(exp[c])[0]) + ")"
                                                  : " (extra " + shown(header_[c]) + ")"),
          {source_, header_line_, static_cast<std::int64_t>(c + 1)});
    }
  }
  for (std::size_t a = 0; a < header_.size(); ++a)
    for (std::size_t b = a + 1; b < header_.size(); ++b)
      if (!header_[a].empty() && header_[a] == header_[b] && opt_.expected_header.empty() && !opt_.ragged)
        throw InputError("duplicate column name " + shown(header_[b]),
                         {source_, header_line_, static_cast<std::int64_t>(b + 1)});
  if (columns_ == 0)
    columns_ = header_.size();
  else if (!opt_.ragged && header_.size() != columns_)
    throw InputError(fmt::format("header has {} columns, expected {}", header_.size(), columns_),
                     {source_, header_line_, 0});
}

std::optional<std::size_t> CsvReader::find_column(std::string_view name) const {
  for (std::size_t c = 0; c < header_.size(); ++c)
    if (header_[c] == name) return c;
  return std::nullopt;
}

std::size_t CsvReader::column(std::string_view name) const {
  if (auto c = find_column(name)) return *c;
  throw InputError("missing column " + shown(name) + " in the header", {source_, header_line_, 0});
}

bool CsvReader::next() {
  std::string_view line;
  while (next_line(line)) {
    if (is_blank_or_comment(line)) continue;
    unquoted_.clear();
    split(line, line_, fields_, &numbers_);
    if (columns_ == 0) columns_ = fields_.size();
    if (!opt_.ragged && fields_.size() != columns_) {
      const std::size_t col = std::min(fields_.size(), columns_) + 1;
      throw InputError(fmt::format("expected {} columns, found {}{}", columns_, fields_.size(),
                                   unterminated_ ? " (the last line has no line end: the file looks cut short)" : ""),
                       {source_, line_, static_cast<std::int64_t>(col)});
    }
    if (unterminated_ && !opt_.ragged)
      log::warn("{}:{}: the last line has no line end: the file may have been cut short (check that line's last "
                "value)",
                source_, line_);
    ++rows_;
    if (opt_.stamp_column >= 0 && opt_.stamp_order != StampOrder::kAny) {
      const auto c = static_cast<std::size_t>(opt_.stamp_column);
      const bool strict = opt_.stamp_order == StampOrder::kStrictlyIncreasing;
      bool ok = true;
      std::string now, before;  // formatted only for the error message
      if (opt_.stamp_kind == StampKind::kNanoseconds) {
        const std::int64_t t = get_int64(c);
        if (have_prev_stamp_) ok = strict ? t > prev_ns_ : t >= prev_ns_;
        if (!ok) {
          now = std::to_string(t);
          before = std::to_string(prev_ns_);
        }
        prev_ns_ = t;
      } else {
        const double t = parse_double(c, false);
        if (have_prev_stamp_) ok = strict ? t > prev_s_ : t >= prev_s_;
        if (!ok) {
          now = format_double(t);
          before = format_double(prev_s_);
        }
        prev_s_ = t;
      }
      if (!ok)
        throw error(c, fmt::format("timestamp {} is {} the previous one ({} at line {}); rows must be {}",
                                   now, strict ? "not after" : "before", before, prev_stamp_line_,
                                   strict ? "strictly increasing in time" : "sorted by time"));
      have_prev_stamp_ = true;
      prev_stamp_line_ = line_;
    }
    return true;
  }
  return false;
}

InputError CsvReader::error(std::size_t i, const std::string& message) const {
  const std::string key = i < header_.size() ? header_[i] : std::string();
  return InputError(message, {source_, line_, static_cast<std::int64_t>(i + 1), key});
}

InputError CsvReader::row_error(const std::string& message) const {
  return InputError(message, {source_, line_, 0});
}

std::string_view CsvReader::field(std::size_t i) const {
  if (i >= fields_.size())
    throw error(i, fmt::format("missing field (the row has {} fields)", fields_.size()));
  return fields_[i];
}

double CsvReader::parse_double(std::size_t i, bool allow_nonfinite) const {
  std::string_view f = field(i);
  if (f.empty()) throw error(i, "empty field, expected a number");
  if (i >= numeric_.size()) numeric_.resize(i + 1, 0);
  numeric_[i] = 1;  // from the next row on, parsed while splitting
  double v = 0.0;
  if (i < numbers_.size() && numbers_[i].parsed) {  // parsed while the row was split: the whole field, no '+'
    v = numbers_[i].value;
    if (numbers_[i].ec == std::errc::result_out_of_range) throw error(i, "number out of range: " + shown(f));
  } else {
    std::string_view s = f;
    if (s.front() == '+') s.remove_prefix(1);
    if (s.empty() || s.front() == '+') throw error(i, "not a number: " + shown(f));
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v, std::chars_format::general);
    if (r.ec == std::errc::invalid_argument) throw error(i, "not a number: " + shown(f));
    if (r.ec == std::errc::result_out_of_range) throw error(i, "number out of range: " + shown(f));
    if (r.ptr != s.data() + s.size()) throw error(i, "trailing characters after the number: " + shown(f));
  }
  if (!allow_nonfinite && !std::isfinite(v)) throw error(i, "non-finite value " + shown(f) + " not allowed");
  return v;
}

double CsvReader::get_double(std::size_t i) const { return parse_double(i, opt_.allow_nonfinite); }
double CsvReader::get_double_nonfinite(std::size_t i) const { return parse_double(i, true); }
double CsvReader::get_double_or_nan(std::size_t i) const {
  if (field(i).empty()) return std::numeric_limits<double>::quiet_NaN();
  return parse_double(i, opt_.allow_nonfinite);
}

std::int64_t CsvReader::get_int64(std::size_t i) const {
  std::string_view f = field(i);
  if (f.empty()) throw error(i, "empty field, expected an integer");
  std::string_view s = f;
  if (s.front() == '+') s.remove_prefix(1);
  if (s.empty() || s.front() == '+') throw error(i, "not an integer: " + shown(f));
  std::int64_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v, 10);
  if (r.ec == std::errc::invalid_argument) throw error(i, "not an integer: " + shown(f));
  if (r.ec == std::errc::result_out_of_range) throw error(i, "integer out of range: " + shown(f));
  if (r.ptr != s.data() + s.size()) throw error(i, "not an integer (trailing characters): " + shown(f));
  return v;
}

int CsvReader::get_int(std::size_t i) const {
  const std::int64_t v = get_int64(i);
  if (v < INT_MIN || v > INT_MAX) throw error(i, "integer out of range: " + shown(field(i)));
  return static_cast<int>(v);
}

std::int64_t CsvReader::get_seconds_ns(std::size_t i) const {
  const std::string_view f = field(i);
  if (f.empty()) throw error(i, "empty field, expected a time in seconds");
  if (auto ns = parse_seconds_ns(f)) return *ns;
  (void)parse_double(i, false);  // reports what is wrong with the number, if anything
  throw error(i, "time in seconds out of range: " + shown(f));
}

std::optional<std::int64_t> parse_seconds_ns(std::string_view s) {
  // value = ±digits × 10^exp10, with the digits read from the text so nothing is rounded early: the
  // integer part's digits and then the fraction's, as one sequence (no copy).
  bool negative = false;
  if (!s.empty() && (s.front() == '+' || s.front() == '-')) {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  std::size_t k = 0;
  while (k < s.size() && s[k] >= '0' && s[k] <= '9') ++k;
  const std::string_view int_digits = s.substr(0, k);
  std::string_view frac_digits;
  if (k < s.size() && s[k] == '.') {
    const std::size_t from = ++k;
    while (k < s.size() && s[k] >= '0' && s[k] <= '9') ++k;
    frac_digits = s.substr(from, k - from);
  }
  const std::size_t n_digits = int_digits.size() + frac_digits.size();
  if (n_digits == 0) return std::nullopt;
  const auto digit = [&](std::size_t i) {  // the i-th digit of the sequence, as a number
    return static_cast<std::uint64_t>((i < int_digits.size() ? int_digits[i] : frac_digits[i - int_digits.size()]) - '0');
  };
  long exp10 = -static_cast<long>(frac_digits.size());
  if (k < s.size() && (s[k] == 'e' || s[k] == 'E')) {
    ++k;
    int e = 0;
    const char* b = s.data() + k;
    if (k < s.size() && s[k] == '+') ++b;
    const auto r = std::from_chars(b, s.data() + s.size(), e);
    if (r.ec != std::errc() || r.ptr != s.data() + s.size() || b == s.data() + s.size()) return std::nullopt;
    if (e > 400 || e < -400) return std::nullopt;
    exp10 += e;
    k = s.size();
  }
  if (k != s.size()) return std::nullopt;
  // Scale to nanoseconds: shift by 9 decimal places; digits below a nanosecond are dropped, rounding
  // half away from zero on the first of them.
  exp10 += 9;
  std::size_t keep = n_digits;
  bool round_up = false;
  if (exp10 < 0) {
    const auto drop = static_cast<std::size_t>(-exp10);
    keep = drop > n_digits ? 0 : n_digits - drop;
    round_up = drop <= n_digits && digit(keep) >= 5;
    exp10 = 0;
  }
  std::size_t first = 0;  // leading zeros do not count towards the 19 digits an int64 holds
  while (first < keep && digit(first) == 0) ++first;
  if (first < keep && keep - first + static_cast<std::size_t>(exp10) > 19) return std::nullopt;
  std::uint64_t mag = 0;  // at most 19 digits: below 2^64
  for (std::size_t i = first; i < keep; ++i) mag = mag * 10 + digit(i);
  if (first < keep)
    for (long z = 0; z < exp10; ++z) mag *= 10;
  if (round_up) ++mag;
  if (mag > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return std::nullopt;
  const auto v = static_cast<std::int64_t>(mag);
  return negative ? -v : v;
}

namespace {
// Writes `t_ns` as seconds with exactly 9 decimals into `out` (at least 32 chars); returns the end.
// Split on the magnitude so INT64_MIN and negative stamps keep their sign once.
char* write_seconds_ns(char* out, std::int64_t t_ns) {
  const bool negative = t_ns < 0;
  const std::uint64_t mag =
      negative ? 0 - static_cast<std::uint64_t>(t_ns) : static_cast<std::uint64_t>(t_ns);
  if (negative) *out++ = '-';
  out = std::to_chars(out, out + 24, mag / 1'000'000'000ULL).ptr;
  *out++ = '.';
  std::uint64_t frac = mag % 1'000'000'000ULL;
  for (int i = 8; i >= 0; --i, frac /= 10) out[i] = static_cast<char>('0' + frac % 10);
  return out + 9;
}

// Shortest round-trip text of a finite double, exactly as fmt's "{}" writes it (the format the run
// files have always had), into `out` (at least 32 chars; the longest is 24); returns the end. A char
// buffer and a compiled format spare fmt's growing-buffer path, the bulk of the writer's time.
char* write_double(char* out, double v) { return fmt::format_to(out, FMT_COMPILE("{}"), v); }
}  // namespace

std::string format_seconds_ns(std::int64_t t_ns) {
  char buf[32];
  return std::string(buf, write_seconds_ns(buf, t_ns));
}

// -------------------------------------------------------------------------------------------------
// CsvWriter
// -------------------------------------------------------------------------------------------------

std::string format_double(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return fmt::format("{}", v);
}

CsvWriter::CsvWriter(char delimiter) : delim_(delimiter) {}

CsvWriter& CsvWriter::comment(std::string_view text, std::string_view prefix) {
  ROE_CHECK(row_fields_ == 0, "comment inside a row");
  out_.append(prefix).append(text).push_back('\n');
  return *this;
}

CsvWriter& CsvWriter::header(const std::vector<std::string>& names, std::string_view prefix) {
  ROE_CHECK(row_fields_ == 0 && rows_ == 0, "header after rows");
  out_.append(prefix);
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i) out_.push_back(delim_);
    out_.append(names[i]);
  }
  out_.push_back('\n');
  header_cols_ = names.size();
  return *this;
}

void CsvWriter::sep() {
  if (row_fields_++) out_.push_back(delim_);
}

CsvWriter& CsvWriter::add(double v) {
  sep();
  if (std::isfinite(v)) {
    char buf[32];
    out_.append(buf, write_double(buf, v));
  } else {
    out_.append(format_double(v));
  }
  return *this;
}

CsvWriter& CsvWriter::add(std::int64_t v) {
  sep();
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out_.append(buf, r.ptr);
  return *this;
}

CsvWriter& CsvWriter::add(int v) { return add(static_cast<std::int64_t>(v)); }

CsvWriter& CsvWriter::add(std::string_view s) {
  sep();
  const bool needs_quotes = std::any_of(s.begin(), s.end(),
                                        [&](char c) { return c == '"' || c == '\n' || c == '\r' || c == delim_; }) ||
                            (!s.empty() && (is_space(s.front()) || is_space(s.back())));
  if (!needs_quotes) {
    out_.append(s);
    return *this;
  }
  ROE_CHECK(delim_ != ' ' && delim_ != '\t' && s.find_first_of("\n\r") == std::string_view::npos,
            "field cannot be written in this table: " + std::string(s));
  out_.push_back('"');
  for (char c : s) {
    if (c == '"') out_.push_back('"');
    out_.push_back(c);
  }
  out_.push_back('"');
  return *this;
}

CsvWriter& CsvWriter::add_fixed(double v, int decimals) {
  sep();
  if (!std::isfinite(v)) {
    out_.append(format_double(v));
  } else {
    out_.append(fmt::format("{:.{}f}", v, decimals));
  }
  return *this;
}

CsvWriter& CsvWriter::add_seconds(std::int64_t t_ns) {
  sep();
  char buf[32];
  out_.append(buf, write_seconds_ns(buf, t_ns));
  return *this;
}

CsvWriter& CsvWriter::add_empty() {
  sep();
  return *this;
}

CsvWriter& CsvWriter::end_row() {
  ROE_CHECK(header_cols_ == 0 || row_fields_ == header_cols_,
            fmt::format("row has {} fields, header has {}", row_fields_, header_cols_));
  out_.push_back('\n');
  row_fields_ = 0;
  ++rows_;
  return *this;
}

void CsvWriter::write(const fs::path& file, bool overwrite) const {
  ROE_CHECK(row_fields_ == 0, "unfinished row");
  write_file_atomic(file, out_, overwrite);
}

void CsvWriter::flush_to(AtomicFile& file, std::size_t min_bytes) {
  ROE_CHECK(row_fields_ == 0, "unfinished row");
  if (out_.size() < min_bytes || out_.empty()) return;
  file.append(out_);
  out_.clear();
}

}  // namespace roe::io
