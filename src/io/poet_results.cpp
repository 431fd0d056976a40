#include "roe/io/poet_results.hpp"

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <Eigen/LU>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <set>

#include "roe/core/error.hpp"
#include "roe/io/output.hpp"
#include "roe/math/so3.hpp"

namespace roe::io {
namespace {

// ------------------------------------------------------------------------------------------------
// A small JSON reader that keeps the line/column of every value and accepts the three non-standard
// number tokens Python's json.dump writes for non-finite floats (NaN, Infinity, -Infinity).
// Rewriting those tokens in the text before handing it to nlohmann would be fragile (they may also
// appear inside strings, e.g. an image called "NaN_1.png"), so the tokenizer handles them itself.
// ------------------------------------------------------------------------------------------------
struct Node {
  enum Kind { kNull, kBool, kNumber, kString, kArray, kObject } kind = kNull;
  bool boolean = false;
  double number = 0.0;
  bool integral = false;  // written without fraction/exponent and fits int64
  std::int64_t integer = 0;
  std::string str;
  std::vector<Node> items;
  std::vector<std::pair<std::string, Node>> members;
  std::vector<std::int64_t> member_lines, member_cols;  // where each member's key starts
  std::int64_t line = 0, col = 0;
};

class LenientParser {
 public:
  LenientParser(const std::string& text, std::string source) : s_(text), source_(std::move(source)) {}

  Node parse_document() {
    skip_ws();
    Node n = value(0);
    skip_ws();
    if (pos_ != s_.size()) fail("unexpected text after the JSON document");
    return n;
  }

  /// A member of the top-level object: its key, where the key starts, and its value.
  using MemberSink = std::function<void(std::string&&, std::int64_t, std::int64_t, Node&&)>;

  /// The document when it is an object, member by member: each value goes to `sink` as soon as it is parsed
  /// and is dropped after, so memory is one member's tree (an image's detections), not the file's. Returns
  /// the document itself when it is not an object (no member was passed then), else an empty object node.
  Node stream_document(const MemberSink& sink) {
    skip_ws();
    if (peek() != '{') return parse_document();
    Node n;
    n.line = line_;
    n.col = col_;
    object(n, 0, &sink);
    values_left_ = kUnlimited;
    skip_ws();
    if (pos_ != s_.size()) fail("unexpected text after the JSON document");
    return n;
  }

 private:
  [[noreturn]] void fail(const std::string& msg) const { throw InputError(msg, {source_, line_, col_}); }

  static constexpr std::size_t kUnlimited = std::numeric_limits<std::size_t>::max();
  std::size_t values_left_ = kUnlimited;  ///< JSON values the current image's entry may still hold

  char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  void advance() {
    if (pos_ >= s_.size()) return;
    if (s_[pos_] == '\n') {
      ++line_;
      col_ = 1;
    } else if ((static_cast<unsigned char>(s_[pos_]) & 0xC0) != 0x80) {
      ++col_;  // count UTF-8 code points, not bytes
    }
    ++pos_;
  }
  void skip_ws() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\n' || s_[pos_] == '\r'))
      advance();
  }
  bool match_word(const char* w) {
    const std::size_t n = std::char_traits<char>::length(w);
    if (s_.compare(pos_, n, w) != 0) return false;
    // The word must not run on into an identifier ("NaNx").
    if (pos_ + n < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[pos_ + n])) || s_[pos_ + n] == '_'))
      return false;
    for (std::size_t i = 0; i < n; ++i) advance();
    return true;
  }

  Node value(int depth) {
    if (depth > 64) fail("JSON nested too deeply");
    if (values_left_-- == 0)
      fail(fmt::format("more than {} JSON values in one image's entry (roe's per-image limit for a PoET "
                       "results.json, docs/infer.md)",
                       kMaxPoetValuesPerImage));
    Node n;
    n.line = line_;
    n.col = col_;
    const char c = peek();
    if (c == '{') {
      object(n, depth);
    } else if (c == '[') {
      array(n, depth);
    } else if (c == '"') {
      n.kind = Node::kString;
      n.str = string_token();
    } else if (match_word("true")) {
      n.kind = Node::kBool;
      n.boolean = true;
    } else if (match_word("false")) {
      n.kind = Node::kBool;
    } else if (match_word("null")) {
      n.kind = Node::kNull;
    } else if (match_word("NaN")) {
      n.kind = Node::kNumber;
      n.number = std::numeric_limits<double>::quiet_NaN();
    } else if (match_word("Infinity")) {
      n.kind = Node::kNumber;
      n.number = std::numeric_limits<double>::infinity();
    } else if (c == '-' && s_.compare(pos_, 9, "-Infinity") == 0) {
      advance();
      match_word("Infinity");
      n.kind = Node::kNumber;
      n.number = -std::numeric_limits<double>::infinity();
    } else if (c == '-' || std::isdigit(static_cast<unsigned char>(c))) {
      number(n);
    } else if (c == '\0') {
      fail("unexpected end of file");
    } else {
      fail(std::string("unexpected character '") + c + "'");
    }
    return n;
  }

  void object(Node& n, int depth, const MemberSink* sink = nullptr) {
    n.kind = Node::kObject;
    advance();  // {
    skip_ws();
    if (peek() == '}') {
      advance();
      return;
    }
    std::map<std::string, std::pair<std::int64_t, std::int64_t>> seen;
    while (true) {
      skip_ws();
      if (peek() != '"') fail("expected a string key");
      const std::int64_t kl = line_, kc = col_;
      std::string key = string_token();
      auto it = seen.find(key);
      if (it != seen.end()) {
        // What a duplicate means depends on the level: image ids, then detection indices per image.
        const char* meaning = depth == 0   ? "; in a PoET results.json this means two images with the same id"
                              : depth == 1 ? "; in a PoET results.json this means two detections with the same index"
                                           : "";
        throw InputError("duplicate key \"" + key + "\" (first at line " + std::to_string(it->second.first) + ")" +
                             meaning,
                         {source_, kl, kc, key});
      }
      seen.emplace(key, std::make_pair(kl, kc));
      skip_ws();
      if (peek() != ':') fail("expected ':' after a key");
      advance();
      skip_ws();
      if (sink) {
        values_left_ = kMaxPoetValuesPerImage;  // one image's tree at a time is in memory: bounded
        (*sink)(std::move(key), kl, kc, value(depth + 1));
      } else {
        if (depth == 1 && n.members.size() == kMaxPoetDetectionsPerImage)
          throw InputError(fmt::format("more than {} detections in one image (roe's per-image limit for a PoET "
                                       "results.json, docs/infer.md; PoET itself writes at most one per query)",
                                       kMaxPoetDetectionsPerImage),
                           {source_, kl, kc, key});
        n.members.emplace_back(std::move(key), value(depth + 1));
        n.member_lines.push_back(kl);
        n.member_cols.push_back(kc);
      }
      skip_ws();
      if (peek() == ',') {
        advance();
        continue;
      }
      if (peek() == '}') {
        advance();
        return;
      }
      fail("expected ',' or '}' in an object");
    }
  }

  void array(Node& n, int depth) {
    n.kind = Node::kArray;
    advance();  // [
    skip_ws();
    if (peek() == ']') {
      advance();
      return;
    }
    while (true) {
      skip_ws();
      n.items.push_back(value(depth + 1));
      skip_ws();
      if (peek() == ',') {
        advance();
        continue;
      }
      if (peek() == ']') {
        advance();
        return;
      }
      fail("expected ',' or ']' in an array");
    }
  }

  std::string string_token() {
    advance();  // opening quote
    std::string out;
    while (true) {
      if (pos_ >= s_.size()) fail("unterminated string");
      const char c = s_[pos_];
      if (c == '"') {
        advance();
        return out;
      }
      if (static_cast<unsigned char>(c) < 0x20) fail("control character in a string");
      if (c != '\\') {
        out.push_back(c);
        advance();
        continue;
      }
      advance();
      const char e = peek();
      switch (e) {
        case '"': out.push_back('"'); break;
        case '\\': out.push_back('\\'); break;
        case '/': out.push_back('/'); break;
        case 'b': out.push_back('\b'); break;
        case 'f': out.push_back('\f'); break;
        case 'n': out.push_back('\n'); break;
        case 'r': out.push_back('\r'); break;
        case 't': out.push_back('\t'); break;
        case 'u': {
          advance();
          unsigned cp = hex4();
          if (cp >= 0xD800 && cp < 0xDC00) {  // surrogate pair
            if (peek() != '\\') fail("unpaired UTF-16 surrogate in a string");
            advance();
            if (peek() != 'u') fail("unpaired UTF-16 surrogate in a string");
            advance();
            const unsigned lo = hex4();
            if (lo < 0xDC00 || lo > 0xDFFF) fail("invalid UTF-16 surrogate pair in a string");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          }
          append_utf8(out, cp);
          continue;  // hex4 already advanced past the digits
        }
        default: fail("invalid escape in a string");
      }
      advance();
    }
  }

  unsigned hex4() {
    unsigned v = 0;
    for (int i = 0; i < 4; ++i) {
      const char h = peek();
      v <<= 4;
      if (h >= '0' && h <= '9') v |= static_cast<unsigned>(h - '0');
      else if (h >= 'a' && h <= 'f') v |= static_cast<unsigned>(h - 'a' + 10);
      else if (h >= 'A' && h <= 'F') v |= static_cast<unsigned>(h - 'A' + 10);
      else fail("invalid \\u escape in a string");
      advance();
    }
    return v;
  }

  static void append_utf8(std::string& out, unsigned cp) {
    if (cp < 0x80) {
      out.push_back(static_cast<char>(cp));
    } else if (cp < 0x800) {
      out.push_back(static_cast<char>(0xC0 | (cp >> 6)));
      out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    } else if (cp < 0x10000) {
      out.push_back(static_cast<char>(0xE0 | (cp >> 12)));
      out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    } else {
      out.push_back(static_cast<char>(0xF0 | (cp >> 18)));
      out.push_back(static_cast<char>(0x80 | ((cp >> 12) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    }
  }

  void number(Node& n) {
    const std::size_t start = pos_;
    bool integral = true;
    if (peek() == '-') advance();
    if (!std::isdigit(static_cast<unsigned char>(peek()))) fail("invalid number");
    if (peek() == '0') {
      advance();
    } else {
      while (std::isdigit(static_cast<unsigned char>(peek()))) advance();
    }
    if (peek() == '.') {
      integral = false;
      advance();
      if (!std::isdigit(static_cast<unsigned char>(peek()))) fail("invalid number");
      while (std::isdigit(static_cast<unsigned char>(peek()))) advance();
    }
    if (peek() == 'e' || peek() == 'E') {
      integral = false;
      advance();
      if (peek() == '+' || peek() == '-') advance();
      if (!std::isdigit(static_cast<unsigned char>(peek()))) fail("invalid number");
      while (std::isdigit(static_cast<unsigned char>(peek()))) advance();
    }
    const std::string tok = s_.substr(start, pos_ - start);
    n.kind = Node::kNumber;
    n.number = std::strtod(tok.c_str(), nullptr);
    if (integral) {
      errno = 0;
      const long long v = std::strtoll(tok.c_str(), nullptr, 10);
      if (errno == 0) {
        n.integral = true;
        n.integer = v;
      }
    }
  }

  const std::string& s_;
  std::string source_;
  std::size_t pos_ = 0;
  std::int64_t line_ = 1, col_ = 1;
};

const char* kind_name(Node::Kind k) {
  switch (k) {
    case Node::kNull: return "null";
    case Node::kBool: return "a boolean";
    case Node::kNumber: return "a number";
    case Node::kString: return "a string";
    case Node::kArray: return "an array";
    case Node::kObject: return "an object";
  }
  return "?";
}

// Strict non-negative decimal integer without sign or leading zeros ("0", "17"), as PoET writes.
bool parse_index(const std::string& s, int& out) {
  if (s.empty() || s.size() > 9) return false;
  if (s.size() > 1 && s[0] == '0') return false;
  for (char c : s)
    if (!std::isdigit(static_cast<unsigned char>(c))) return false;
  out = std::stoi(s);
  return true;
}

/// The largest |t| component accepted: a kilometre, far beyond what a 6-DoF pose network sees.
constexpr double kMaxTranslationM = 1000.0;

class ResultsBuilder {
 public:
  ResultsBuilder(std::string source, PoetRotationFormat fmt) : source_(std::move(source)), fmt_(fmt) {}

  [[noreturn]] void fail(const Node& n, const std::string& msg, const std::string& key) const {
    throw InputError(msg, {source_, n.line, n.col, key});
  }

  double num(const Node& n, const std::string& key) const {
    if (n.kind != Node::kNumber) fail(n, std::string("expected a number, found ") + kind_name(n.kind), key);
    return n.number;
  }

  /// One top-level member "<img_id>": {detections}.
  PoetImageResult image(const std::string& id, std::int64_t line, std::int64_t column, const Node& img) const {
    PoetImageResult r;
    r.id = id;
    r.line = line;
    r.column = column;
    if (img.kind != Node::kObject)
      fail(img, std::string("expected an object of detections, found ") + kind_name(img.kind), id);
    r.detections.reserve(img.members.size());
    for (std::size_t k = 0; k < img.members.size(); ++k) {
      const auto& [idx_key, det] = img.members[k];
      const std::string key = id + "." + idx_key;
      PoetRawDetection d;
      if (!parse_index(idx_key, d.index))
        throw InputError("detection keys must be \"0\", \"1\", ... (PoET's score order), found \"" + idx_key + "\"",
                         {source_, img.member_lines[k], img.member_cols[k], key});
      d.line = img.member_lines[k];
      d.column = img.member_cols[k];
      detection(det, key, d);
      r.detections.push_back(std::move(d));
    }
    std::sort(r.detections.begin(), r.detections.end(),
              [](const PoetRawDetection& a, const PoetRawDetection& b) { return a.index < b.index; });
    return r;
  }

 private:
  void detection(const Node& det, const std::string& key, PoetRawDetection& d) const {
    if (det.kind != Node::kObject) fail(det, std::string("expected a detection object, found ") + kind_name(det.kind), key);
    bool has_t = false, has_rot = false, has_class = false;
    RawUncertainty u;
    for (const auto& [k, v] : det.members) {
      const std::string kk = key + "." + k;
      if (k == "pred_translation_aleatoric" || k == "t_aleatoric") {
        u.take(u.t_logvar, v, kk, *this);
      } else if (k == "pred_rotation_aleatoric" || k == "rot_aleatoric") {
        u.take(u.r_logvar, v, kk, *this);
      } else if (k == "cov" || k == "covariance") {
        u.take(u.cov, v, kk, *this);
      } else if (k == "t") {
        has_t = true;
        if (v.kind != Node::kArray || v.items.size() != 3) fail(v, "\"t\" must be [x, y, z] (metres)", kk);
        for (int i = 0; i < 3; ++i) {
          d.t[i] = num(v.items[i], kk);
          // A finite value beyond any camera's range is a broken output, not a pose (NaN/Inf are dropped).
          if (std::isfinite(d.t[i]) && std::abs(d.t[i]) > kMaxTranslationM)
            fail(v.items[i], fmt::format("translation {:g} m is not an object pose in a camera's view (|t| must be "
                                         "at most {:g} m)", d.t[i], kMaxTranslationM), kk);
        }
      } else if (k == "rot") {
        has_rot = true;
        rotation(v, kk, d);
      } else if (k == "box") {
        if (v.kind != Node::kArray || v.items.size() != 4) fail(v, "\"box\" must be [cx, cy, w, h]", kk);
        for (int i = 0; i < 4; ++i) d.box[i] = num(v.items[i], kk);
      } else if (k == "class") {
        has_class = true;
        if (v.kind != Node::kNumber || !std::isfinite(v.number) || v.number != std::floor(v.number))
          fail(v, "\"class\" must be an integer class id", kk);
        if (v.number < 1 || v.number > 1e6)
          fail(v, "\"class\" must be a 1-based class id (0 is PoET's background, -1 its padding)", kk);
        d.class_id = static_cast<int>(v.number);
      } else if (k == "score") {
        const double s = num(v, kk);
        if (std::isfinite(s)) d.score = s;
      } else {
        fail(v, "unknown key \"" + k + "\" in a PoET detection (expected t, rot, box, class, score, and for the "
                "uncertainty pred_translation_aleatoric + pred_rotation_aleatoric, or cov)", kk);
      }
    }
    if (!has_t) fail(det, "detection without \"t\"", key);
    if (!has_rot) fail(det, "detection without \"rot\"", key);
    if (!has_class) fail(det, "detection without \"class\"", key);
    d.finite = d.t.allFinite() && d.R_C_O.allFinite();
    uncertainty(u, d);
  }

  /// The uncertainty keys of one detection, as found (validated once all keys are known).
  struct RawUncertainty {
    const Node* t_logvar = nullptr;
    const Node* r_logvar = nullptr;
    const Node* cov = nullptr;
    std::string t_key, r_key, cov_key;
    void take(const Node*& slot, const Node& v, const std::string& kk, const ResultsBuilder& b) {
      std::string& where = &slot == &t_logvar ? t_key : &slot == &r_logvar ? r_key : cov_key;
      if (slot) b.fail(v, "given twice, as " + where + " and " + kk + " (two spellings of one value)", kk);
      slot = &v;
      where = kk;
    }
  };

  void uncertainty(const RawUncertainty& u, PoetRawDetection& d) const {
    if (u.cov && (u.t_logvar || u.r_logvar))
      fail(*u.cov, "a detection has both aleatoric log-variances and a covariance: give one of them", u.cov_key);
    if (!u.t_logvar != !u.r_logvar) {
      const bool has_t = u.t_logvar != nullptr;
      fail(has_t ? *u.t_logvar : *u.r_logvar,
           std::string(has_t ? "translation" : "rotation") + " log-variances without the " +
               (has_t ? "rotation" : "translation") +
               " ones (pred_rotation_aleatoric / pred_translation_aleatoric): the sigma columns need all six axes",
           has_t ? u.t_key : u.r_key);
    }
    // A detection whose pose is not finite is dropped: its values are checked for shape only.
    Vector6d s;
    if (u.t_logvar) {
      log_variances(*u.t_logvar, u.t_key, d.finite, s.head<3>());
      log_variances(*u.r_logvar, u.r_key, d.finite, s.tail<3>());
      d.uncertainty = PoetRawDetection::Uncertainty::kLogVariance;
    } else if (u.cov) {
      s = covariance(*u.cov, u.cov_key, d.finite, d.max_abs_correlation);
      d.uncertainty = PoetRawDetection::Uncertainty::kCovariance;
    } else {
      return;
    }
    if (d.finite) d.sigma = s;
  }

  /// [s_x, s_y, s_z], s = log σ² (PoET's aleatoric heads) → σ = exp(s / 2).
  void log_variances(const Node& v, const std::string& kk, bool check, Eigen::Ref<Eigen::Vector3d> sigma) const {
    if (v.kind != Node::kArray || v.items.size() != 3)
      fail(v, "must be [s_x, s_y, s_z], three log-variances s = log σ² (found " +
                  (v.kind == Node::kArray ? std::to_string(v.items.size()) + " elements)" : std::string(kind_name(v.kind)) + ")"),
           kk);
    for (int i = 0; i < 3; ++i) {
      const std::string ek = kk + "[" + std::to_string(i) + "]";
      const double s = num(v.items[i], ek);
      if (!check) continue;
      if (!std::isfinite(s)) fail(v.items[i], "a log-variance must be a finite number", ek);
      // exp(±600) stays a normal double, and so does σ² after the filter's mapping.
      if (std::abs(s) > 600.0)
        fail(v.items[i], "log-variance " + fmt_num(s) + " is outside [-600, 600]: σ² = exp(s) would under- or overflow", ek);
      sigma[i] = std::exp(0.5 * s);
    }
  }

  /// A 6x6 covariance (list of rows) of (t, rotation vector) → the square roots of its diagonal.
  Vector6d covariance(const Node& v, const std::string& kk, bool check, double& max_abs_corr) const {
    const std::string shape = "must be a 6x6 covariance, a list of 6 rows of 6 numbers (t in m, rotation in rad)";
    if (v.kind != Node::kArray || v.items.size() != 6) fail(v, shape, kk);
    Eigen::Matrix<double, 6, 6> C;
    for (int r = 0; r < 6; ++r) {
      const Node& row = v.items[r];
      if (row.kind != Node::kArray || row.items.size() != 6) fail(row, shape, kk + "[" + std::to_string(r) + "]");
      for (int c = 0; c < 6; ++c) C(r, c) = num(row.items[c], element(kk, r, c));
    }
    Vector6d sigma = Vector6d::Zero();
    if (!check) return sigma;
    auto at = [&](int r, int c) -> const Node& { return v.items[r].items[c]; };
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c)
        if (!std::isfinite(C(r, c))) fail(at(r, c), "covariance elements must be finite numbers", element(kk, r, c));
    for (int i = 0; i < 6; ++i)
      if (!(C(i, i) > 0.0))
        fail(at(i, i), "variance " + fmt_num(C(i, i)) + " on the diagonal must be > 0", element(kk, i, i));
    for (int r = 0; r < 6; ++r)
      for (int c = r + 1; c < 6; ++c)
        if (std::abs(C(r, c) - C(c, r)) > 1e-5 * std::sqrt(C(r, r) * C(c, c)))
          fail(at(c, r), "the covariance is not symmetric: [" + std::to_string(r) + "][" + std::to_string(c) + "] = " +
                             fmt_num(C(r, c)) + " but [" + std::to_string(c) + "][" + std::to_string(r) + "] = " + fmt_num(C(c, r)),
               element(kk, c, r));
    // Positive semi-definite, judged on the correlation matrix (units differ: m² and rad²).
    const Vector6d d = C.diagonal().cwiseSqrt();
    const Eigen::Matrix<double, 6, 6> rho = d.cwiseInverse().asDiagonal() * (0.5 * (C + C.transpose())) * d.cwiseInverse().asDiagonal();
    const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(rho, Eigen::EigenvaluesOnly).eigenvalues()(0);
    if (min_eig < -1e-6)
      fail(v, "the covariance is not positive semi-definite (smallest eigenvalue of its correlation matrix " +
                  fmt_num(min_eig) + ")", kk);
    max_abs_corr = (rho - Eigen::Matrix<double, 6, 6>::Identity()).cwiseAbs().maxCoeff();
    return d;
  }

  static std::string element(const std::string& kk, int r, int c) {
    return kk + "[" + std::to_string(r) + "][" + std::to_string(c) + "]";
  }
  static std::string fmt_num(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", x);
    return buf;
  }

  void rotation(const Node& v, const std::string& kk, PoetRawDetection& d) const {
    if (v.kind != Node::kArray) fail(v, "\"rot\" must be a 3x3 list of rows or a [w, x, y, z] quaternion", kk);
    const bool is_matrix = v.items.size() == 3;
    const bool is_quat = v.items.size() == 4;
    if (!is_matrix && !is_quat)
      fail(v, "\"rot\" must be a 3x3 list of rows or a [w, x, y, z] quaternion (found " +
                  std::to_string(v.items.size()) + " elements)", kk);
    if (fmt_ == PoetRotationFormat::kMatrix && !is_matrix)
      fail(v, "\"rot\" is a 4-vector but --rotation matrix was given", kk);
    if (fmt_ == PoetRotationFormat::kQuatWxyz && !is_quat)
      fail(v, "\"rot\" is not a 4-vector but --rotation quat_wxyz was given", kk);
    if (is_matrix) {
      Eigen::Matrix3d R;
      for (int r = 0; r < 3; ++r) {
        const Node& row = v.items[r];
        if (row.kind != Node::kArray || row.items.size() != 3) fail(row, "each row of \"rot\" must have 3 numbers", kk);
        for (int c = 0; c < 3; ++c) R(r, c) = num(row.items[c], kk);
      }
      if (R.allFinite()) {
        const double orth = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
        if (orth > 1e-3 || R.determinant() < 0.0)
          fail(v, "\"rot\" is not a rotation matrix (max |RᵀR − I| = " + std::to_string(orth) +
                      ", det = " + std::to_string(R.determinant()) + ")", kk);
        R = math::orthonormalize(R);  // float32 output printed as float64: remove the rounding
      }
      d.R_C_O = R;
    } else {
      Eigen::Vector4d q;
      for (int i = 0; i < 4; ++i) q[i] = num(v.items[i], kk);
      d.rot_was_quaternion = true;
      if (q.allFinite()) {
        const double n = q.norm();
        if (std::abs(n - 1.0) > 1e-3)
          fail(v, "\"rot\" quaternion [w, x, y, z] is not unit norm (norm " + std::to_string(n) + ")", kk);
        d.R_C_O = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
      } else {
        d.R_C_O.setConstant(std::numeric_limits<double>::quiet_NaN());
      }
    }
  }

  std::string source_;
  PoetRotationFormat fmt_;
};

}  // namespace

PoetRotationFormat parse_poet_rotation_format(const std::string& s, const std::string& what) {
  if (s == "auto") return PoetRotationFormat::kAuto;
  if (s == "matrix") return PoetRotationFormat::kMatrix;
  if (s == "quat_wxyz") return PoetRotationFormat::kQuatWxyz;
  throw InputError("unknown rotation format \"" + s + "\" (expected auto, matrix or quat_wxyz)", {what});
}

PoetResults parse_poet_results(const std::string& text, const std::string& source, PoetRotationFormat format) {
  // A CSV (a roe detections.csv, a trajectory) is not PoET's output: say what it is, not "invalid JSON".
  const std::size_t first = text.find_first_not_of(" \t\r\n\xEF\xBB\xBF");
  const std::string line = first == std::string::npos ? "" : text.substr(first, text.find('\n', first) - first);
  if (!line.empty() && line[0] != '{' && line[0] != '[' && line.find(',') != std::string::npos)
    throw InputError("this looks like a CSV file (first line \"" + line.substr(0, 60) +
                         "\"), not PoET's results.json: `roe import poet` reads the JSON PoET's inference_engine.py "
                         "writes (docs/infer.md); a roe detections.csv is used as it is, from "
                         "DATASET/detections/NAME/detections.csv",
                     {source, 1, 1});
  LenientParser p(text, source);
  const ResultsBuilder b(source, format);
  PoetResults out;
  const Node root = p.stream_document([&](std::string&& id, std::int64_t line, std::int64_t col, Node&& img) {
    out.images.push_back(b.image(id, line, col, img));
  });
  if (root.kind != Node::kObject)
    b.fail(root, std::string("a PoET results.json must be an object of image ids, found ") + kind_name(root.kind), "");
  return out;
}

PoetResults read_poet_results(const std::filesystem::path& file, PoetRotationFormat format) {
  return parse_poet_results(read_file(file), file.string(), format);
}

std::string poet_image_id(const std::string& filename) {
  const std::string name = std::filesystem::path(filename).filename().string();
  // Python's name[name.find('_') + 1 : name.rfind('.')] (PoET's inference_engine.py): find gives −1
  // without an underscore (the slice starts at 0), rfind −1 without a dot (the slice ends one
  // character before the end), and an end before the start gives "".
  const auto us = name.find('_');
  const auto dot = name.rfind('.');
  const std::size_t start = us == std::string::npos ? 0 : us + 1;
  const std::size_t end = dot == std::string::npos ? (name.empty() ? 0 : name.size() - 1) : dot;
  return end <= start ? std::string() : name.substr(start, end - start);
}

const std::vector<std::string>& ycbv_class_names() {
  // aau-cns/poet dataset_files/ycbv_classes.json (= BOP YCB-V object ids 1..21).
  static const std::vector<std::string> names = {
      "background",          "002_master_chef_can", "003_cracker_box",   "004_sugar_box",
      "005_tomato_soup_can", "006_mustard_bottle",  "007_tuna_fish_can", "008_pudding_box",
      "009_gelatin_box",     "010_potted_meat_can", "011_banana",        "019_pitcher_base",
      "021_bleach_cleanser", "024_bowl",            "025_mug",           "035_power_drill",
      "036_wood_block",      "037_scissors",        "040_large_marker",  "051_large_clamp",
      "052_extra_large_clamp", "061_foam_brick"};
  return names;
}

std::vector<std::string> read_poet_class_names(const std::filesystem::path& file) {
  const std::string text = read_file(file);
  LenientParser p(text, file.string());
  const Node root = p.parse_document();
  if (root.kind != Node::kObject)
    throw InputError("a class-info file must be an object {\"1\": \"name\", ...}", {file.string(), root.line, root.col});
  std::vector<std::string> names;
  for (std::size_t i = 0; i < root.members.size(); ++i) {
    const auto& [k, v] = root.members[i];
    int id = 0;
    if (!parse_index(k, id))
      throw InputError("class ids must be non-negative integers written as strings", {file.string(), root.member_lines[i], root.member_cols[i], k});
    if (v.kind != Node::kString)
      throw InputError("class names must be strings", {file.string(), v.line, v.col, k});
    if (static_cast<std::size_t>(id) >= names.size()) names.resize(static_cast<std::size_t>(id) + 1);
    names[static_cast<std::size_t>(id)] = v.str;
  }
  return names;
}

}  // namespace roe::io
