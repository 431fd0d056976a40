// libFuzzer target: the generic CSV reader under each option set roe's readers use (header or not,
// comma or whitespace, ragged, quotes, stamp order and kind, non-finite values), every field read
// through every typed getter.
#include "fuzz_support.hpp"
#include "roe/io/csv.hpp"

namespace {
roe::io::CsvOptions options(std::uint8_t b) {
  roe::io::CsvOptions o;
  o.header = b & 1 ? roe::io::CsvHeader::kFirstLine : roe::io::CsvHeader::kNone;
  o.whitespace_delimited = (b >> 1) & 1;
  o.ragged = (b >> 2) & 1;
  o.quotes = (b >> 3) & 1;
  o.allow_nonfinite = (b >> 4) & 1;
  o.stamp_column = (b >> 5) & 1 ? 0 : -1;
  o.stamp_kind = (b >> 6) & 1 ? roe::io::StampKind::kSeconds : roe::io::StampKind::kNanoseconds;
  o.stamp_order = (b >> 7) & 1 ? roe::io::StampOrder::kNonDecreasing : roe::io::StampOrder::kStrictlyIncreasing;
  if (o.header == roe::io::CsvHeader::kFirstLine && (b & 6) == 0) o.expected_header = {"#timestamp [ns]|t", "x", "y"};
  return o;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const roe::io::CsvOptions o = options(data[0]);
  roe::fuzz::expect_clean([&] {
    auto r = roe::io::CsvReader::from_text(roe::fuzz::text(data + 1, size - 1), "fuzz.csv", o);
    (void)r.find_column("x");
    while (r.next()) {
      for (std::size_t c = 0; c < r.size(); ++c) {
        roe::fuzz::expect_clean([&] { (void)r.get_int64(c); });
        roe::fuzz::expect_clean([&] { (void)r.get_int(c); });
        roe::fuzz::expect_clean([&] { (void)r.get_double(c); });
        roe::fuzz::expect_clean([&] { (void)r.get_double_or_nan(c); });
        roe::fuzz::expect_clean([&] { (void)r.get_seconds_ns(c); });
      }
      roe::fuzz::expect_clean([&] { (void)r.field(r.size()); });
    }
  });
  return 0;
}
