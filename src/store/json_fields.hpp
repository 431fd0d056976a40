#pragma once
// The store's one JSON dialect (store-private): a file's mapping is written once, as a set of
// `template <class A> void fields(A& a, T& v)` functions (one per block), and walked both ways: by Writer<D>,
// which writes each field, and by Reader<D>, which reads each field strictly (a missing or mistyped key is an
// error naming the file and the key path). The model is basalt's single `serialize`: the keys are spelled
// once, so the writer and the reader cannot drift apart.
//
// D, the dialect of one file (report.json, run.json, roe.json, meta.json, the sweep's files), is a struct
// declared in the same namespace as the file's `fields` functions (they are found through D by argument-
// dependent lookup, wherever they are declared before the end of the file). It supplies:
//   static constexpr bool kStrictKeys;    // a key no field reads is an error (io::JsonObject::finish, with its
//                                         // "did you mean the top-level ..." and typo hints)
//   static constexpr bool kNullIsAbsent;  // an omittable or defaulted key given as null reads as absent
//   [[noreturn]] static void fail(const std::string& file, const std::string& path, Problem, const std::string&
//                                 detail);  // throws the file's error (its words: phrase() or config_words())
// and, optionally, leaf types of its own (a Pose with the file's quaternion tolerance):
//   static json write_leaf(const T&);
//   static void read_leaf(const json&, T&, const std::string& file, const std::string& path);
//
// The walkers' verbs, as a mapping uses them (`a` is a Writer<D> or a Reader<D>; A::kReading tells which):
//   a(key, v)              required: always written; missing when read is Problem::kMissing
//   a.opt(key, v)          defaulted: always written; absent (or null, kNullIsAbsent) keeps v's default
//   a.opt(key, v, written) the same, written only where `written` (a key left out at its default)
//   a.omittable(key, o)    std::optional: written only when set; absent reads as unset
//   a.omittable(key, o, present)  the same, but the reader requires the key when `present` and refuses it
//                          (reads nothing: a strict dialect's unknown key) when not
//   a.fixed(key, value)    a fixed text or a derived value: written, never read (a strict reader knows the key)
//   a.nested(key, f)       an object whose fields are f(a') (an inline block without a struct of its own)
//   a.axes(key, v, names)  an Eigen::Vector3d as {names[0]: x, names[1]: y, names[2]: z}
//   a.check(key, ok, what) reading only: Problem::kInvalid at key unless ok (a value's own rule)
//   a.custom(key, w, r)    a value with its own JSON form: w() returns it; r(const json* x, file, path) reads it
//                          (x null when absent)
//   a.merge(w, r)          keys of this object owned by another mapping (io's IMU noise): w(json& object) adds
//                          them, r(io::JsonObject& object) reads them
//   a.rest(details)        the object's other keys, kept as they are (after every other field; not with merge):
//                          written under the mapped keys, read as every key no field read
//   a.peek(key)            reading: the raw value of key (nullptr when absent), not marked as read; writing:
//                          nullptr (for a mapping whose layout depends on the file's: a legacy block)
// Values: bool, integers (range-checked), floating point (null reads as NaN, as JSON writes a NaN), std::string,
// nlohmann::json (an object), std::optional (null = unset), std::vector, std::array (its length checked),
// Eigen::Vector3d (an array of 3 numbers), std::map keyed by text or by an integer (written as its decimal
// text), the dialect's leaves, and any struct with a `fields` mapping.
#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "roe/core/error.hpp"
#include "roe/io/json.hpp"

namespace roe::store::json_fields {

using io::json;

/// What is wrong with a value, for the dialect to word.
enum class Problem {
  kMissing,      ///< a required key is absent
  kNotObject,    ///< an object was expected
  kNotBool,      ///< true or false was expected
  kNotNumber,    ///< a number was expected
  kNotInteger,   ///< an integer was expected
  kNotCount,     ///< an integer >= 0 was expected
  kOutOfRange,   ///< an integer beyond its type's range; detail: "(min to max)"
  kNotString,    ///< a string was expected
  kNotArray,     ///< an array was expected
  kWrongLength,  ///< an array of another length; detail: the expected length
  kBadKey,       ///< a map key that is not an integer (an object id)
  kInvalid,      ///< a value against its own rule; detail: the rule's message
};

/// The problem as report.json's reader words it after the key path: "is missing", "is not a number", ...
inline std::string phrase(Problem p, const std::string& detail) {
  switch (p) {
    case Problem::kMissing: return "is missing";
    case Problem::kNotObject: return "is not an object";
    case Problem::kNotBool: return "is not true or false";
    case Problem::kNotNumber: return "is not a number";
    case Problem::kNotInteger: return "is not an integer";
    case Problem::kNotCount: return "is not a count (an integer >= 0)";
    case Problem::kOutOfRange: return "is out of range " + detail;
    case Problem::kNotString: return "is not a string";
    case Problem::kNotArray: return "is not an array";
    case Problem::kWrongLength: return "is not an array of the expected length (" + detail + ")";
    case Problem::kBadKey: return "is not an object id";
    case Problem::kInvalid: return detail;
  }
  return detail;
}

/// The problem in io::JsonObject's words (the configs' and manifests' readers): "expected a number", ...
/// `missing`: the words for Problem::kMissing.
inline std::string config_words(Problem p, const std::string& detail, const char* missing = "missing required key") {
  switch (p) {
    case Problem::kMissing: return missing;
    case Problem::kNotObject: return "expected a JSON object";
    case Problem::kNotBool: return "expected true or false";
    case Problem::kNotNumber: return "expected a number";
    case Problem::kNotInteger: return "expected an integer";
    case Problem::kNotCount: return "expected an integer >= 0";
    case Problem::kOutOfRange: return "integer out of range " + detail;
    case Problem::kNotString: return "expected a string";
    case Problem::kNotArray: return "expected an array";
    case Problem::kWrongLength: return "expected " + detail + " numbers";
    case Problem::kBadKey: return "expected an object id";
    case Problem::kInvalid: return detail;
  }
  return detail;
}

// ---- type traits -------------------------------------------------------------------------------------

template <class T>
struct IsOptional : std::false_type {};
template <class T>
struct IsOptional<std::optional<T>> : std::true_type {};
template <class T>
struct IsVector : std::false_type {};
template <class T>
struct IsVector<std::vector<T>> : std::true_type {};
template <class T>
struct IsArray : std::false_type {};
template <class T, std::size_t N>
struct IsArray<std::array<T, N>> : std::true_type {};
template <class T>
struct IsMap : std::false_type {};
template <class K, class T>
struct IsMap<std::map<K, T>> : std::true_type {};

/// Whether the dialect D has a leaf form of T (D::write_leaf / D::read_leaf).
template <class D, class T, class = void>
struct HasLeaf : std::false_type {};
template <class D, class T>
struct HasLeaf<D, T, std::void_t<decltype(D::write_leaf(std::declval<const T&>()))>> : std::true_type {};

/// Whether T is read and written through a `fields` mapping (an object of its own).
template <class D, class T>
constexpr bool kIsMapped = !(std::is_same_v<T, json> || std::is_arithmetic_v<T> || std::is_same_v<T, std::string> ||
                             IsOptional<T>::value || IsVector<T>::value || IsArray<T>::value || IsMap<T>::value ||
                             std::is_same_v<T, Eigen::Vector3d> || HasLeaf<D, T>::value);

template <class K>
std::string map_key(const K& k) {
  if constexpr (std::is_same_v<K, std::string>) {
    return k;
  } else {
    static_assert(std::is_integral_v<K>, "a map is keyed by text or by an integer");
    return std::to_string(k);
  }
}

// ---- the writer ----------------------------------------------------------------------------------------

/// Writes each field into the object `j`. Fixed texts and derived values are written, never read.
template <class D>
struct Writer {
  static constexpr bool kReading = false;
  json& j;

  template <class T>
  static json value(const T& v) {
    if constexpr (HasLeaf<D, T>::value) {
      return D::write_leaf(v);
    } else if constexpr (std::is_same_v<T, json> || std::is_arithmetic_v<T> || std::is_same_v<T, std::string>) {
      return json(v);
    } else if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      return json::array({v.x(), v.y(), v.z()});
    } else if constexpr (IsOptional<T>::value) {
      return v ? value(*v) : json(nullptr);
    } else if constexpr (IsVector<T>::value || IsArray<T>::value) {
      json out = json::array();
      for (const auto& x : v) out.push_back(value(x));
      return out;
    } else if constexpr (IsMap<T>::value) {
      json out = json::object();
      for (const auto& [k, x] : v) out[map_key(k)] = value(x);
      return out;
    } else {
      json out = json::object();
      Writer w{out};
      fields(w, const_cast<T&>(v));  // the mapping is shared with the reader; the writer only reads v
      return out;
    }
  }

  template <class T>
  void operator()(const char* key, const T& v) {
    j[key] = value(v);
  }
  template <class T>
  void opt(const char* key, const T& v, bool written = true) {
    if (written) j[key] = value(v);
  }
  template <class T>
  void omittable(const char* key, const std::optional<T>& v, bool = true) {
    if (v) j[key] = value(*v);
  }
  void fixed(const char* key, json v) { j[key] = std::move(v); }
  const json* peek(const char*) const { return nullptr; }
  template <class F>
  void nested(const char* key, F&& fields) {
    json sub = json::object();
    Writer w{sub};
    fields(w);
    j[key] = std::move(sub);
  }
  void axes(const char* key, const Eigen::Vector3d& v, const char* const (&names)[3]) {
    j[key] = {{names[0], v.x()}, {names[1], v.y()}, {names[2], v.z()}};
  }
  void check(const char*, bool, const char*) const {}
  void check(const char*, bool, const std::string&) const {}
  template <class W, class R>
  void custom(const char* key, W&& write, R&&) {
    j[key] = write();
  }
  template <class W, class R>
  void merge(W&& write, R&&) {
    write(j);
  }
  /// Under the keys written so far: `rest`'s keys that none of them is.
  void rest(const json& rest) {
    if (!rest.is_object()) return;
    for (const auto& [k, x] : rest.items())
      if (!j.contains(k)) j[k] = x;
  }
};

// ---- the reader ----------------------------------------------------------------------------------------

/// Reads each field from the object `o` (which marks the keys read; a strict dialect's reader calls its
/// finish()), strictly: a missing or mistyped key is D::fail with the file and the key path.
template <class D>
struct Reader {
  static constexpr bool kReading = true;
  io::JsonObject& o;  ///< marks the keys read
  const json& j;      ///< the same object
  std::vector<std::string> seen{};  ///< the keys read so far (for rest())

  const std::string& file() const { return o.source(); }
  std::string at(const char* key) const { return o.key_path(key); }
  [[noreturn]] void fail(const char* key, Problem p, const std::string& detail = {}) const {
    D::fail(file(), at(key), p, detail);
  }

  /// `x` at `path` of `file` as v; an object-valued T is read with a reader of its own (its keys checked
  /// within itself, as an array element's are).
  template <class T>
  static void value(const json& x, T& v, const std::string& file, const std::string& path) {
    const auto need = [&](bool ok, Problem p, const std::string& detail = {}) {
      if (!ok) D::fail(file, path, p, detail);
    };
    if constexpr (HasLeaf<D, T>::value) {
      D::read_leaf(x, v, file, path);
    } else if constexpr (std::is_same_v<T, json>) {
      need(x.is_object(), Problem::kNotObject);
      v = x;
    } else if constexpr (std::is_same_v<T, bool>) {
      need(x.is_boolean(), Problem::kNotBool);
      v = x.get<bool>();
    } else if constexpr (std::is_floating_point_v<T>) {
      need(x.is_number() || x.is_null(), Problem::kNotNumber);  // null: a NaN, as JSON writes it
      v = x.is_null() ? std::numeric_limits<T>::quiet_NaN() : x.get<T>();
    } else if constexpr (std::is_integral_v<T>) {
      read_integer(x, v, file, path);
    } else if constexpr (std::is_same_v<T, std::string>) {
      need(x.is_string(), Problem::kNotString);
      v = x.get<std::string>();
    } else if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      need(x.is_array(), Problem::kNotArray);
      need(x.size() == 3, Problem::kWrongLength, "3");
      for (int i = 0; i < 3; ++i) value(x[static_cast<std::size_t>(i)], v[i], file, fmt::format("{}[{}]", path, i));
    } else if constexpr (IsOptional<T>::value) {
      v.reset();
      if (x.is_null()) return;
      v.emplace();
      value(x, *v, file, path);
    } else if constexpr (IsVector<T>::value) {
      need(x.is_array(), Problem::kNotArray);
      v.clear();
      v.resize(x.size());
      for (std::size_t i = 0; i < x.size(); ++i) value(x[i], v[i], file, fmt::format("{}[{}]", path, i));
    } else if constexpr (IsArray<T>::value) {
      need(x.is_array(), Problem::kNotArray);
      need(x.size() == v.size(), Problem::kWrongLength, std::to_string(v.size()));
      for (std::size_t i = 0; i < v.size(); ++i) value(x[i], v[i], file, fmt::format("{}[{}]", path, i));
    } else if constexpr (IsMap<T>::value) {
      need(x.is_object(), Problem::kNotObject);
      v.clear();
      for (const auto& [k, e] : x.items()) {
        const std::string at = path.empty() ? k : path + "." + k;
        value(e, v[map_key_from<typename T::key_type>(k, file, at)], file, at);
      }
    } else {
      need(x.is_object(), Problem::kNotObject);
      io::JsonObject sub(x, file, path);
      Reader r{sub, x};
      fields(r, v);
      if constexpr (D::kStrictKeys) sub.finish();
    }
  }

  template <class T>
  void operator()(const char* key, T& v) {
    const json* x = raw(key);
    if (!x) fail(key, Problem::kMissing);
    member(key, *x, v);
  }
  template <class T>
  void opt(const char* key, T& v, bool = true) {
    const json* x = raw(key);
    if (!x || (D::kNullIsAbsent && x->is_null())) return;
    member(key, *x, v);
  }
  template <class T>
  void omittable(const char* key, std::optional<T>& v) {
    v.reset();
    const json* x = raw(key);
    if (!x || (D::kNullIsAbsent && x->is_null())) return;
    v.emplace();
    member(key, *x, *v);
  }
  template <class T>
  void omittable(const char* key, std::optional<T>& v, bool present) {
    v.reset();
    if (!present) return;
    v.emplace();
    (*this)(key, *v);
  }
  template <class V>
  void fixed(const char* key, const V&) {
    (void)raw(key);
  }
  const json* peek(const char* key) const {
    const auto it = j.find(key);
    return it == j.end() ? nullptr : &*it;
  }
  template <class F>
  void nested(const char* key, F&& fields) {
    const json* x = raw(key);
    if (!x) fail(key, Problem::kMissing);
    if (!x->is_object()) fail(key, Problem::kNotObject);
    io::JsonObject sub = o.child(key);
    Reader r{sub, *x};
    fields(r);
    sub.finish();  // a child's unknown key is reported by its root's finish()
  }
  void axes(const char* key, Eigen::Vector3d& v, const char* const (&names)[3]) {
    nested(key, [&](Reader& r) {
      for (int i = 0; i < 3; ++i) r(names[i], v[i]);
    });
  }
  void check(const char* key, bool ok, const std::string& what) const {
    if (!ok) fail(key, Problem::kInvalid, what);
  }
  template <class W, class R>
  void custom(const char* key, W&&, R&& read) {
    read(raw(key), file(), at(key));
  }
  template <class W, class R>
  void merge(W&&, R&& read) {
    read(o);
  }

 /// The keys of this object that no field read so far, as they are (meta.json's producer record).
  void rest(json& out) {
    out = json::object();
    for (const auto& [k, x] : j.items())
      if (std::find(seen.begin(), seen.end(), k) == seen.end()) out[k] = x, (void)raw(k.c_str());
  }

 private:
  const json* raw(const char* key) {
    if (std::find(seen.begin(), seen.end(), key) == seen.end()) seen.emplace_back(key);
    return o.raw(key);
  }

  /// A member `key` of this object: an object-valued T shares this document's key tree (its unknown keys get
  /// the document's hints).
  template <class T>
  void member(const char* key, const json& x, T& v) {
    if constexpr (kIsMapped<D, T>) {
      if (!x.is_object()) fail(key, Problem::kNotObject);
      io::JsonObject sub = o.child(key);
      Reader r{sub, x};
      fields(r, v);
      sub.finish();
    } else {
      value(x, v, file(), at(key));
    }
  }

  template <class T>
  static void read_integer(const json& x, T& v, const std::string& file, const std::string& path) {
    const Problem kind = std::is_unsigned_v<T> ? Problem::kNotCount : Problem::kNotInteger;
    if (!x.is_number_integer()) D::fail(file, path, kind, {});
    const bool fits =
        x.is_number_unsigned()
            ? x.get<std::uint64_t>() <= static_cast<std::uint64_t>(std::numeric_limits<T>::max())
            : x.get<std::int64_t>() >= static_cast<std::int64_t>(std::numeric_limits<T>::min()) &&
                  (std::is_unsigned_v<T> ||
                   x.get<std::int64_t>() <= static_cast<std::int64_t>(std::numeric_limits<T>::max()));
    if (!fits) {
      if (std::is_unsigned_v<T> && x.is_number_integer() && !x.is_number_unsigned()) D::fail(file, path, kind, {});
      D::fail(file, path, Problem::kOutOfRange,
              fmt::format("({} to {})", std::numeric_limits<T>::min(), std::numeric_limits<T>::max()));
    }
    v = x.get<T>();
  }

  template <class K>
  static K map_key_from(const std::string& k, const std::string& file, const std::string& path) {
    if constexpr (std::is_same_v<K, std::string>) {
      return k;
    } else {
      static_assert(std::is_integral_v<K>, "a map is keyed by text or by an integer");
      try {
        std::size_t used = 0;
        const long long n = std::stoll(k, &used);
        if (used == k.size() && n >= static_cast<long long>(std::numeric_limits<K>::min()) &&
            n <= static_cast<long long>(std::numeric_limits<K>::max()))
          return static_cast<K>(n);
      } catch (const std::exception&) {
      }
      D::fail(file, path, Problem::kBadKey, {});
    }
  }
};

// ---- whole documents -----------------------------------------------------------------------------------

/// v as its JSON document in dialect D.
template <class D, class T>
json write(const T& v) {
  return Writer<D>::value(v);
}

/// The document `j` of `file` read as T in dialect D (a strict dialect refuses a key no field reads).
template <class D, class T>
void read(const json& j, T& v, const std::string& file) {
  if (!j.is_object()) D::fail(file, "", Problem::kNotObject, {});
  io::JsonObject root(j, file);
  Reader<D> r{root, j};
  fields(r, v);
  if constexpr (D::kStrictKeys) root.finish();
}

}  // namespace roe::store::json_fields
