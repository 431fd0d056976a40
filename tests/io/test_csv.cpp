#include <unistd.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "support/test_util.hpp"
#include "roe/io/csv.hpp"
#include "roe/io/output.hpp"

namespace fs = std::filesystem;
using roe::InputError;
using roe::io::CsvHeader;
using roe::io::CsvOptions;
using roe::io::CsvReader;
using roe::io::CsvWriter;
using roe::io::StampKind;
using roe::io::StampOrder;

namespace {

// Runs `fn` and returns the InputError it throws (fails the test when it throws nothing).
using roe::test::expect_input_error;

// Reads every row of `text` (forcing a parse of each field as double except column 0 as int64).
void read_all(const std::string& text, CsvOptions o) {
  auto r = CsvReader::from_text(text, "t.csv", o);
  while (r.next()) {
    (void)r.get_int64(0);
    for (std::size_t c = 1; c < r.size(); ++c) (void)r.get_double(c);
  }
}

CsvOptions imu_like() {
  CsvOptions o;
  o.expected_header = {"timestamp [ns]", "x", "y"};
  o.stamp_column = 0;
  return o;
}

}  // namespace

TEST_CASE("csv: reads a EuRoC-style table with comment header, CRLF and blank lines", "[csv]") {
  const std::string text = "#timestamp [ns],x,y\r\n10,1.5,-2\r\n\r\n# a comment\r\n20,1e-3,+4\r\n   \n30,0,7";
  auto r = CsvReader::from_text(text, "t.csv", imu_like());
  REQUIRE(r.header() == std::vector<std::string>{"timestamp [ns]", "x", "y"});
  REQUIRE(r.header_line() == 1);
  REQUIRE(r.next());
  CHECK(r.line() == 2);
  CHECK(r.get_int64(0) == 10);
  CHECK(r.get_double(1) == 1.5);
  CHECK(r.get_double(2) == -2.0);
  REQUIRE(r.next());
  CHECK(r.line() == 5);
  CHECK(r.get_double(1) == 1e-3);
  CHECK(r.get_double(2) == 4.0);
  REQUIRE(r.next());
  CHECK(r.line() == 7);
  CHECK(r.get_int64(0) == 30);
  CHECK_FALSE(r.next());
  CHECK(r.rows() == 3);
}

TEST_CASE("csv: header names are trimmed and alternatives accepted", "[csv]") {
  CsvOptions o;
  o.expected_header = {"timestamp [ns]|timestamp", "p [m]"};
  auto r = CsvReader::from_text("#timestamp, p [m]\n1, 2\n", "t.csv", o);
  REQUIRE(r.next());
  CHECK(r.get_double(1) == 2.0);
  auto r2 = CsvReader::from_text("\xEF\xBB\xBF#timestamp [ns],p [m]\n1,2\n", "t.csv", o);  // BOM
  REQUIRE(r2.next());

  // Every alternative of a three-way spec matches on its own, the middle one included; a prefix or a
  // concatenation of alternatives does not.
  o.expected_header = {"t [ns]|t [s]|t", "p [m]"};
  for (const char* name : {"t [ns]", "t [s]", "t"}) {
    auto r3 = CsvReader::from_text(std::string("#") + name + ",p [m]\n1,2\n", "t.csv", o);
    CHECK(r3.header()[0] == name);
  }
  for (const char* name : {"t [", "t [s]|t", "t [ns]|t [s]"}) {
    auto e = expect_input_error([&] { (void)CsvReader::from_text(std::string("#") + name + ",p [m]\n1,2\n", "t.csv", o); });
    CHECK(e.context().column == 1);
    CHECK(std::string(e.what()).find("'t [ns]' or 't [s]' or 't'") != std::string::npos);
  }
}

TEST_CASE("csv: bad header reports the header line and the column", "[csv]") {
  auto e = expect_input_error([] { read_all("#timestamp [ns],x,z\n1,2,3\n", imu_like()); });
  CHECK(e.context().file == "t.csv");
  CHECK(e.context().line == 1);
  CHECK(e.context().column == 3);
  CHECK(std::string(e.what()).find("'z'") != std::string::npos);

  e = expect_input_error([] { read_all("\n\n#timestamp [ns],x\n1,2\n", imu_like()); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 3);  // the missing column

  e = expect_input_error([] { read_all("#timestamp [ns],x,y,w\n1,2,3,4\n", imu_like()); });
  CHECK(e.context().line == 1);
  CHECK(e.context().column == 4);  // the extra column

  e = expect_input_error([] { read_all("", imu_like()); });
  CHECK(e.context().line == 1);
  CHECK(std::string(e.what()).find("missing header") != std::string::npos);
}

TEST_CASE("csv: wrong column counts report line and column", "[csv]") {
  auto e = expect_input_error([] { read_all("#timestamp [ns],x,y\n1,2,3\n2,3\n", imu_like()); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 3);  // first missing field
  CHECK(std::string(e.what()).find("expected 3 columns, found 2") != std::string::npos);
  CHECK(std::string(e.what()).find("t.csv:3:3") == 0);

  e = expect_input_error([] { read_all("#timestamp [ns],x,y\r\n1,2,3\r\n\r\n2,3,4,5\r\n", imu_like()); });
  CHECK(e.context().line == 4);
  CHECK(e.context().column == 4);  // first extra field

  // A trailing delimiter is an extra (empty) field.
  e = expect_input_error([] { read_all("#timestamp [ns],x,y\n1,2,3,\n", imu_like()); });
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 4);

  // Without a header the first row fixes the count.
  CsvOptions o;
  o.header = CsvHeader::kNone;
  e = expect_input_error([&] { read_all("1,2,3\n2,3,4\n3,4\n", o); });
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 3);
}

TEST_CASE("csv: non-numbers and trailing garbage report line and column", "[csv]") {
  struct Case {
    std::string row;
    std::int64_t column;
    std::string what;
  };
  const std::vector<Case> cases = {
      {"10,abc,1", 2, "not a number"},
      {"10,1.5x,1", 2, "trailing characters"},
      {"10,1.5,1 2", 3, "trailing characters"},
      {"10,,1", 2, "empty field"},
      {"10,1,1e999", 3, "out of range"},
      {"10,1,++1", 3, "not a number"},
      {"10,1,0x10", 3, "trailing characters"},
      {"1.5,1,1", 1, "not an integer"},
      {"1e9,1,1", 1, "not an integer"},
      {"abc,1,1", 1, "not an integer"},
      {"99999999999999999999,1,1", 1, "out of range"},
  };
  for (const auto& c : cases) {
    CAPTURE(c.row);
    auto e = expect_input_error([&] { read_all("#timestamp [ns],x,y\n5,0,0\n" + c.row + "\n", imu_like()); });
    CHECK(e.context().line == 3);
    CHECK(e.context().column == c.column);
    CHECK(std::string(e.what()).find(c.what) != std::string::npos);
  }
}

TEST_CASE("csv: NaN and inf are rejected unless allowed", "[csv]") {
  for (const std::string v : {"nan", "NaN", "inf", "-inf", "Infinity"}) {
    CAPTURE(v);
    auto e = expect_input_error([&] { read_all("#timestamp [ns],x,y\n1,0," + v + "\n", imu_like()); });
    CHECK(e.context().line == 2);
    CHECK(e.context().column == 3);
    CHECK(e.context().key == "y");
    CHECK(std::string(e.what()).find("non-finite") != std::string::npos);
  }
  CsvOptions o = imu_like();
  o.allow_nonfinite = true;
  auto r = CsvReader::from_text("#timestamp [ns],x,y\n1,nan,-inf\n", "t.csv", o);
  REQUIRE(r.next());
  CHECK(std::isnan(r.get_double(1)));
  CHECK(std::isinf(r.get_double(2)));
  // Per-call opt-in, and empty → NaN.
  auto r2 = CsvReader::from_text("#timestamp [ns],x,y\n1,nan,\n", "t.csv", imu_like());
  REQUIRE(r2.next());
  CHECK(std::isnan(r2.get_double_nonfinite(1)));
  CHECK(std::isnan(r2.get_double_or_nan(2)));
  CHECK_THROWS_AS(r2.get_double(1), InputError);
}

TEST_CASE("csv: unsorted stamps report the row and the stamp column", "[csv]") {
  auto e = expect_input_error([] { read_all("#timestamp [ns],x,y\n10,0,0\n20,0,0\n20,0,0\n", imu_like()); });
  CHECK(e.context().line == 4);
  CHECK(e.context().column == 1);
  CHECK(std::string(e.what()).find("not after the previous one (20 at line 3)") != std::string::npos);

  e = expect_input_error([] { read_all("#timestamp [ns],x,y\n10,0,0\n# c\n9,0,0\n", imu_like()); });
  CHECK(e.context().line == 4);

  // Non-decreasing allows equal stamps but not going back.
  CsvOptions o = imu_like();
  o.stamp_order = StampOrder::kNonDecreasing;
  CHECK_NOTHROW(read_all("#timestamp [ns],x,y\n10,0,0\n10,1,1\n11,0,0\n", o));
  e = expect_input_error([&] { read_all("#timestamp [ns],x,y\n10,0,0\n10,1,1\n9,0,0\n", o); });
  CHECK(e.context().line == 4);
  CHECK(e.context().column == 1);

  // Seconds as doubles in a whitespace-separated table, stamp in column 0.
  CsvOptions tum;
  tum.whitespace_delimited = true;
  tum.header = CsvHeader::kNone;
  tum.stamp_column = 0;
  tum.stamp_kind = StampKind::kSeconds;
  auto count_rows = [&](const std::string& text) {
    auto r = CsvReader::from_text(text, "t.txt", tum);
    std::size_t n = 0;
    while (r.next()) {
      for (std::size_t c = 0; c < r.size(); ++c) (void)r.get_double(c);
      ++n;
    }
    return n;
  };
  CHECK(count_rows("# timestamp tx ty\n1.5 0 0\n\t1.6   0  0  \r\n# end\n") == 2);
  e = expect_input_error([&] { count_rows("1.5 0 0\n1.6 0 0\n1.55 0 0\n"); });
  CHECK(e.context().file == "t.txt");
  CHECK(e.context().line == 3);
  CHECK(e.context().column == 1);
  e = expect_input_error([&] { count_rows("1.5 0 0\n1.6 0\n"); });
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 3);
}

TEST_CASE("csv: columns by name in any order", "[csv]") {
  CsvOptions o;
  auto r = CsvReader::from_text("qw,t,tx\n1,0.5,2\n", "t.csv", o);
  const std::size_t c_t = r.column("t"), c_tx = r.column("tx"), c_qw = r.column("qw");
  CHECK(c_t == 1);
  CHECK_FALSE(r.find_column("ty").has_value());
  auto e = expect_input_error([&] { (void)r.column("ty"); });
  CHECK(e.context().line == 1);
  CHECK(std::string(e.what()).find("'ty'") != std::string::npos);
  REQUIRE(r.next());
  CHECK(r.get_double(c_t) == 0.5);
  CHECK(r.get_double(c_tx) == 2.0);
  CHECK(r.get_double(c_qw) == 1.0);

  e = expect_input_error([] { auto r2 = CsvReader::from_text("a,b,a\n", "t.csv"); });
  CHECK(e.context().column == 3);
  CHECK(std::string(e.what()).find("duplicate") != std::string::npos);
}

TEST_CASE("csv: quoted fields, ragged rows and caller errors", "[csv]") {
  CsvOptions o;
  o.header = CsvHeader::kNone;
  o.ragged = true;
  auto r = CsvReader::from_text("a,\"b,c\", \"say \"\"hi\"\"\" ,\n1\n", "m.csv", o);
  REQUIRE(r.next());
  REQUIRE(r.size() == 4);
  CHECK(r.field(1) == "b,c");
  CHECK(r.field(2) == "say \"hi\"");
  CHECK(r.is_empty(3));
  REQUIRE(r.next());
  CHECK(r.size() == 1);
  auto e = expect_input_error([&] { (void)r.get_double(2); });
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 3);
  e = r.error(0, "custom");
  CHECK(std::string(e.what()) == "m.csv:2:1: custom");
  CHECK(std::string(r.row_error("bad row").what()) == "m.csv:2: bad row");

  e = expect_input_error([&] {
    auto q = CsvReader::from_text("x\n\"open\n", "q.csv");
    q.next();
  });
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 1);
  e = expect_input_error([&] {
    auto q = CsvReader::from_text("x,y\n1,\"a\"b\n", "q.csv");
    q.next();
  });
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 2);
}

TEST_CASE("csv: int range and file errors", "[csv]") {
  CsvOptions o;
  o.header = CsvHeader::kNone;
  auto r = CsvReader::from_text("3000000000,-5,+7\n", "t.csv", o);
  REQUIRE(r.next());
  CHECK(r.get_int64(0) == 3000000000LL);
  CHECK_THROWS_AS(r.get_int(0), InputError);
  CHECK(r.get_int(1) == -5);
  CHECK(r.get_int(2) == 7);
  auto e = expect_input_error([] { CsvReader q("/nonexistent/roe/file.csv"); });
  CHECK(e.context().file == "/nonexistent/roe/file.csv");
}

TEST_CASE("csv: writer round-trips doubles exactly and is deterministic", "[csv]") {
  const std::vector<double> values = {0.1,
                                      1.0 / 3.0,
                                      -2.5e-300,
                                      1e300,
                                      6.02214076e23,
                                      -0.0,
                                      0.0,
                                      9.81,
                                      1403715523.912140000,
                                      std::nextafter(1.0, 2.0),
                                      std::numeric_limits<double>::denorm_min(),
                                      std::numeric_limits<double>::max()};
  CsvWriter w;
  w.header({"timestamp [ns]", "v", "name"}, "#");
  std::int64_t t = 1403715523912140000LL;
  for (double v : values) w.add(t++).add(v).add("a,\"b\"").end_row();
  CHECK(w.rows() == values.size());
  const fs::path dir = fs::temp_directory_path() / ("roe_test_csv_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path file = dir / "v.csv";
  w.write(file);
  CsvOptions o;
  o.expected_header = {"timestamp [ns]", "v", "name"};
  o.stamp_column = 0;
  CsvReader r(file, o);
  std::size_t i = 0;
  while (r.next()) {
    REQUIRE(i < values.size());
    CHECK(r.get_int64(0) == 1403715523912140000LL + static_cast<std::int64_t>(i));
    const double back = r.get_double(1);
    CHECK(back == values[i]);
    CHECK(std::signbit(back) == std::signbit(values[i]));
    CHECK(r.field(2) == "a,\"b\"");
    ++i;
  }
  CHECK(i == values.size());
  // Same content twice → same bytes.
  CsvWriter w2;
  w2.header({"timestamp [ns]", "v", "name"}, "#");
  t = 1403715523912140000LL;
  for (double v : values) w2.add(t++).add(v).add("a,\"b\"").end_row();
  CHECK(w2.str() == roe::io::read_file(file));
  fs::remove_all(dir);

  CHECK(roe::io::format_double(0.1) == "0.1");
  CHECK(roe::io::format_double(std::nan("")) == "nan");
  CsvWriter f(' ');
  f.add_fixed(1403715523.9121399, 9).add(1.0).add_empty().end_row();
  CHECK(f.str() == "1403715523.912139893 1 \n");
  CsvWriter bad;
  bad.header({"a", "b"});
  bad.add(1.0);
  CHECK_THROWS_AS(bad.end_row(), roe::InternalError);
}

TEST_CASE("csv: decimal seconds to integer nanoseconds, exactly", "[csv][time]") {
  using roe::io::format_seconds_ns;
  using roe::io::parse_seconds_ns;
  CHECK(parse_seconds_ns("1305031102.160407") == 1305031102160407000LL);
  CHECK(parse_seconds_ns("1.403715529112143517e+09") == 1403715529112143517LL);
  CHECK(parse_seconds_ns("1403715523.912140000") == 1403715523912140000LL);
  CHECK(parse_seconds_ns("0.005") == 5'000'000LL);
  CHECK(parse_seconds_ns("+2") == 2'000'000'000LL);
  CHECK(parse_seconds_ns("-0.5") == -500'000'000LL);
  CHECK(parse_seconds_ns(".25") == 250'000'000LL);
  CHECK(parse_seconds_ns("3.") == 3'000'000'000LL);
  CHECK(parse_seconds_ns("5E-3") == 5'000'000LL);
  CHECK(parse_seconds_ns("0") == 0);
  // Beyond nanoseconds: rounded half away from zero.
  CHECK(parse_seconds_ns("0.0000000015") == 2);
  CHECK(parse_seconds_ns("0.0000000014999") == 1);
  CHECK(parse_seconds_ns("-0.0000000015") == -2);
  CHECK(parse_seconds_ns("9e-10") == 1);
  CHECK(parse_seconds_ns("4e-11") == 0);
  CHECK(parse_seconds_ns("1.9999999999") == 2'000'000'000LL);
  // Not numbers / out of range.
  for (const char* bad :
       {"", "-", ".", "abc", "1.5x", "1e", "1e+", "nan", "inf", "1..2", "1e5.5", "9.3e9", "--1"})
    CHECK_FALSE(parse_seconds_ns(bad).has_value());
  CHECK(parse_seconds_ns("9.2e9") == 9'200'000'000'000'000'000LL);
  // The text ends where the view ends, even when digits follow it in memory.
  CHECK(parse_seconds_ns(std::string_view("5e-31234", 4)) == 5'000'000LL);
  CHECK(parse_seconds_ns(std::string_view("1.5e+0999", 6)) == 1'500'000'000LL);
  CHECK(parse_seconds_ns(std::string_view("2.25999", 4)) == 2'250'000'000LL);

  CHECK(format_seconds_ns(1403715523912140000LL) == "1403715523.912140000");
  CHECK(format_seconds_ns(5) == "0.000000005");
  CHECK(format_seconds_ns(-500'000'000LL) == "-0.500000000");
  CHECK(format_seconds_ns(std::numeric_limits<std::int64_t>::min()) == "-9223372036.854775808");
  for (std::int64_t t : {0LL, 1LL, 999'999'999LL, 1'000'000'000LL, 1403715523912140001LL, -7LL})
    CHECK(parse_seconds_ns(format_seconds_ns(t)) == t);

  // Reader and writer.
  CsvWriter w(' ');
  w.add_seconds(1403715523912140000LL).add(1.0).end_row();
  CHECK(w.str() == "1403715523.912140000 1\n");
  CsvOptions o;
  o.whitespace_delimited = true;
  o.header = CsvHeader::kNone;
  auto r = CsvReader::from_text("1.403715529112143517e+09 0\nx 0\n1e30 0\n", "t.txt", o);
  REQUIRE(r.next());
  CHECK(r.get_seconds_ns(0) == 1403715529112143517LL);
  REQUIRE(r.next());
  auto e = expect_input_error([&] { (void)r.get_seconds_ns(0); });
  CHECK(e.context().line == 2);
  CHECK(e.context().column == 1);
  CHECK(std::string(e.what()).find("not a number") != std::string::npos);
  REQUIRE(r.next());
  e = expect_input_error([&] { (void)r.get_seconds_ns(0); });
  CHECK(std::string(e.what()).find("out of range") != std::string::npos);
}

TEST_CASE("csv: random malformed input only ever raises InputError", "[csv][fuzz]") {
  // Text from an alphabet rich in separators, quotes, signs and number parts: every outcome must
  // be rows or a located InputError, never a crash, a hang or another exception type.
  std::mt19937 rng(2024);
  const std::string alphabet = "0123456789,,,..--+e\"\"\n\n\r# \tnaif";
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1), len(0, 120);
  std::size_t errors = 0, tables = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string text;
    const std::size_t n = len(rng);
    for (std::size_t k = 0; k < n; ++k) text += alphabet[pick(rng)];
    CsvOptions o;
    o.header = i % 2 ? CsvHeader::kNone : CsvHeader::kFirstLine;
    o.whitespace_delimited = i % 5 == 0;
    o.stamp_column = i % 3 == 0 ? 0 : -1;
    o.stamp_kind = i % 7 == 0 ? StampKind::kSeconds : StampKind::kNanoseconds;
    o.ragged = i % 11 == 0;
    try {
      auto r = CsvReader::from_text(text, "fuzz.csv", o);
      while (r.next()) {
        for (std::size_t c = 0; c < r.size() + 1; ++c) {
          try {
            (void)r.get_double(c);
          } catch (const InputError& e) {
            REQUIRE(e.context().line == r.line());
            REQUIRE(e.context().column == static_cast<std::int64_t>(c + 1));
          }
          try {
            (void)r.get_seconds_ns(c);
          } catch (const InputError&) {
          }
        }
      }
      ++tables;
    } catch (const InputError& e) {
      REQUIRE(e.context().file == "fuzz.csv");
      REQUIRE(e.context().line >= 1);
      ++errors;
    }
  }
  CHECK(errors > 100);
  CHECK(tables > 100);
}

TEST_CASE("csv: writer/reader round trip of arbitrary text fields", "[csv]") {
  std::mt19937 rng(77);
  const std::string alphabet = "ab,\" \t;x'";
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1), len(0, 12);
  CsvWriter w;
  w.header({"i", "s"});
  std::vector<std::string> values;
  for (int i = 0; i < 500; ++i) {
    std::string s;
    const std::size_t n = len(rng);
    for (std::size_t k = 0; k < n; ++k) s += alphabet[pick(rng)];
    if (!s.empty() && s[0] == '#') s[0] = 'x';
    values.push_back(s);
    w.add(i).add(s).end_row();
  }
  CsvOptions o;
  o.expected_header = {"i", "s"};
  auto r = CsvReader::from_text(w.str(), "w.csv", o);
  int i = 0;
  while (r.next()) {
    REQUIRE(i < 500);
    CHECK(r.get_int(0) == i);
    CHECK(r.field(1) == values[static_cast<std::size_t>(i)]);
    ++i;
  }
  CHECK(i == 500);
}

TEST_CASE("csv: a number parsed while the row is split equals the field's own parse", "[csv]") {
  // From the second row on, CsvReader parses the number of a column read as a number before where it
  // finds the field (the parse finds the field's end); a field that is more than a number falls back to
  // the text. Either way get_double sees the whole field: the same value, and the same error for "1.5x"
  // or "1e999", in every mode, in the first row and in later ones.
  struct Mode {
    const char* name;
    bool whitespace, trim, quotes;
    char delim;
  };
  for (const Mode m : {Mode{"spaces", true, true, true, ' '}, Mode{"comma, trimmed", false, true, true, ','},
                       Mode{"comma, untrimmed", false, false, false, ','}, Mode{"tab", false, true, true, '\t'},
                       Mode{"space-delimited", false, true, true, ' '}}) {
    CAPTURE(m.name);
    CsvOptions o;
    o.header = CsvHeader::kNone;
    o.whitespace_delimited = m.whitespace;
    o.trim = m.trim;
    o.quotes = m.quotes;
    o.delimiter = m.delim;
    o.ragged = true;
    const auto parse = [&](const std::string& field, bool later_row) -> std::string {  // the second field's
      const std::string sep = m.whitespace ? " \t " : std::string(1, m.delim);
      const std::string row = "7" + sep + field + sep + "8\n";
      auto r = CsvReader::from_text(later_row ? "1" + sep + "2" + sep + "3\n" + row : row, "t", o);
      try {
        if (later_row) {
          REQUIRE(r.next());
          for (std::size_t c = 0; c < 3; ++c) CHECK(r.get_double(c) == static_cast<double>(c + 1));
        }
        REQUIRE(r.next());
        const double v = r.get_double(1);
        CHECK(r.get_double(0) == 7.0);
        CHECK(r.get_double(r.size() - 1) == 8.0);
        return std::to_string(v);
      } catch (const InputError& e) {
        return e.bare_message();
      }
    };
    const auto value = [&](const std::string& field) {
      const std::string first = parse(field, false), later = parse(field, true);
      CHECK(first == later);
      return later;
    };
    CHECK(value("1.5") == "1.500000");
    CHECK(value("-2.25e-1") == "-0.225000");
    CHECK(value(".5") == "0.500000");
    CHECK(value("1.5x") == "trailing characters after the number: '1.5x'");
    CHECK(value("1e999") == "number out of range: '1e999'");
    CHECK(value("1e") == "trailing characters after the number: '1e'");
    CHECK(value("+3") == "3.000000");
    CHECK(value("++3") == "not a number: '++3'");
    CHECK(value("nan") == "non-finite value 'nan' not allowed");
    CHECK(value("0x10") == "trailing characters after the number: '0x10'");
    if (m.trim && !m.whitespace && m.delim == ',') {
      CHECK(value("  4.5\t ") == "4.500000");  // spaces around a number are trimmed
      CHECK(value(" 4.5 x ") == "trailing characters after the number: '4.5 x'");
      CHECK(value("\"6.5\"") == "6.500000");  // quoted: unquoted first
    }
    if (!m.trim && !m.whitespace) CHECK(value(" 4.5") == "not a number: ' 4.5'");
  }
}
