// roe sweep: the spec model and its expansion into jobs with content-derived ids (no file is written here).
#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <set>

#include "roe/app/eval.hpp"
#include "roe/app/run.hpp"
#include "roe/app/simulate.hpp"
#include "roe/app/sweep.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/store/dataset.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/sim/simulator.hpp"

namespace roe::app {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {


/// Where in the spec: errors name the key path (`axes.configs[2]`).
struct Where {
  std::string source;
  [[noreturn]] void fail(const std::string& path, const std::string& what) const {
    throw ConfigError(what, {source, 0, 0, path});
  }
};

const json& nonempty_array(const Where& w, const json& j, const std::string& path) {
  if (!j.is_array()) w.fail(path, "expected an array");
  if (j.empty()) w.fail(path, "an axis needs at least one value");
  return j;
}

/// The eval options of every job, with every default filled in (so writing a default changes no id): the
/// settings of for_each_sweep_eval_setting, each checked by run_eval's own rule.
json read_eval(const Where& w, const json* j) {
  EvalOptions o;
  if (j) {
    io::JsonObject r(*j, w.source, "eval");
    for_each_sweep_eval_setting(o, [&r](const char* key, auto& value) { r.get(key, value); });
    r.finish();
  }
  json e = json::object();
  for_each_sweep_eval_setting(o, [&](const char* key, const auto& value) {
    try {
      check_sweep_eval_setting(o, key);
    } catch (const InputError& err) {
      w.fail(std::string("eval.") + key, err.bare_message());
    }
    e[key] = value;
  });
  return e;
}

struct DatasetEntry {
  json label;                   ///< axis value: the preset name or the path as written
  json content;                 ///< the job's "dataset" without the seed
  std::vector<std::int64_t> seeds;  ///< empty: no seed axis for this entry (a folder)
};

std::vector<std::int64_t> read_seeds(const Where& w, const json& j, const std::string& path) {
  std::vector<std::int64_t> seeds;
  nonempty_array(w, j, path);
  for (std::size_t i = 0; i < j.size(); ++i) {
    if (!j[i].is_number_integer() || j[i].get<std::int64_t>() < 0)
      w.fail(fmt::format("{}[{}]", path, i), "a seed is an integer >= 0");
    seeds.push_back(j[i].get<std::int64_t>());
  }
  return seeds;
}

DatasetEntry read_dataset(const Where& w, const json& j, const std::string& path, const fs::path& spec_dir,
                          const std::vector<std::int64_t>& block_seeds) {
  DatasetEntry d;
  std::string preset, dir;
  std::optional<double> duration;
  if (j.is_string()) {
    preset = j.get<std::string>();
  } else if (j.is_object()) {
    io::JsonObject r(j, w.source, path);
    r.get("preset", preset);
    r.get("path", dir);
    if (const json* s = r.raw("seeds")) d.seeds = read_seeds(w, *s, path + ".seeds");
    if (const json* s = r.raw("duration_s")) {
      if (!s->is_number() || !(s->get<double>() > 0.0)) w.fail(path + ".duration_s", "must be a number > 0");
      duration = s->get<double>();
      sim::SimConfig bounds;  // the simulator's own limits, checked now rather than when the job runs
      bounds.duration_s = *duration;
      try {
        sim::validate(bounds);
      } catch (const InputError& e) {
        w.fail(path + ".duration_s", e.bare_message());
      }
    }
    r.finish();
    if (preset.empty() == dir.empty()) w.fail(path, "a dataset is {\"preset\": NAME} or {\"path\": DATASET_DIR}");
  } else {
    w.fail(path, "a dataset is a preset name, {\"preset\": NAME, ...} or {\"path\": DATASET_DIR}");
  }
  if (!preset.empty()) {
    const auto names = list_presets();
    if (std::find(names.begin(), names.end(), preset) == names.end())
      w.fail(j.is_string() ? path : path + ".preset",
             fmt::format("unknown simulator preset '{}' (presets: {})", preset, fmt::join(names, ", ")));
    d.label = preset;
    d.content = {{"preset", preset},
                 {"preset_sha256", io::sha256_hex(preset_text(preset))},
                 {"duration_s", duration ? json(*duration) : json(nullptr)}};
    if (d.seeds.empty()) d.seeds = block_seeds;
    return d;
  }
  if (!d.seeds.empty()) w.fail(path + ".seeds", "seeds apply to simulator presets, not to a dataset folder");
  if (duration) w.fail(path + ".duration_s", "duration_s applies to simulator presets, not to a dataset folder");
  const fs::path p = fs::path(dir).is_absolute() ? fs::path(dir) : spec_dir / dir;
  if (!fs::is_regular_file(store::manifest_path(p)))
    w.fail(path + ".path", fmt::format("not a dataset folder (no roe.json): {}", p.string()));
  d.label = dir;
  d.content = {{"path", io::provenance_path(p)}};
  return d;
}

/// A config of the configs axis: its label and JSON (a shipped name or a file relative to the spec).
std::pair<std::string, json> read_config(const Where& w, const json& j, const std::string& path,
                                         const fs::path& spec_dir) {
  if (!j.is_string()) w.fail(path, "a config is a shipped name (\"paper\") or a JSON file path");
  const std::string name = j.get<std::string>();
  const bool is_path = name.find('/') != std::string::npos || fs::path(name).extension() == ".json";
  try {
    if (!is_path) return {name, io::parse_json_text(shipped_config_text(name), "configs/" + name + ".json")};
    const fs::path p = fs::path(name).is_absolute() ? fs::path(name) : spec_dir / name;
    if (!fs::is_regular_file(p)) w.fail(path, fmt::format("config file not found: {}", p.string()));
    return {name, io::parse_json_file(p)};
  } catch (const ConfigError& e) {
    if (e.context().file == w.source) throw;
    throw ConfigError(e.what(), {w.source, 0, 0, path});
  } catch (const InputError& e) {
    throw ConfigError(e.what(), {w.source, 0, 0, path});
  }
}

/// Sets `dotted` ("filter.chi2_confidence") in `config` after checking that a run config has that key.
void apply_override(const Where& w, json& config, const std::string& dotted, const json& value,
                    const std::string& path) {
  static const json defaults = run_config_to_json(RunConfig{}, true);
  const json* node = &defaults;
  json* target = &config;
  std::size_t start = 0;
  while (true) {
    const std::size_t dot = dotted.find('.', start);
    const std::string key = dotted.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (!node->is_object() || !node->contains(key))
      w.fail(path, fmt::format("'{}' is not a run config key (keys: see configs/default.json and docs/filter.md)",
                               dotted));
    node = &(*node)[key];
    if (!target->is_object()) *target = json::object();
    target = &(*target)[key];
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  if (node->is_object()) w.fail(path, fmt::format("'{}' is a section, not a value", dotted));
  *target = value;
}

struct Variant {
  json axes = json::object();  ///< override key -> value
  json config;
};

/// The configs × override values of one block, each validated by the run config loader.
std::vector<std::pair<std::string, Variant>> read_variants(const Where& w, const json& block,
                                                           const std::string& bpath, const fs::path& spec_dir,
                                                           std::vector<std::string>& override_keys) {
  std::vector<std::pair<std::string, json>> configs;
  if (block.contains("configs")) {
    const json& c = nonempty_array(w, block["configs"], bpath + ".configs");
    for (std::size_t i = 0; i < c.size(); ++i)
      configs.push_back(read_config(w, c[i], fmt::format("{}.configs[{}]", bpath, i), spec_dir));
  } else {
    configs.push_back(read_config(w, "default", bpath + ".configs", spec_dir));
  }
  // Cross product of the override values, in key order.
  std::vector<Variant> combos(1);
  if (block.contains("overrides")) {
    const json& o = block["overrides"];
    if (!o.is_object()) w.fail(bpath + ".overrides", "expected an object {\"filter.KEY\": [values]}");
    for (const auto& [key, values] : o.items()) {
      const std::string opath = fmt::format("{}.overrides.{}", bpath, key);
      nonempty_array(w, values, opath);
      if (std::find(override_keys.begin(), override_keys.end(), key) == override_keys.end())
        override_keys.push_back(key);
      std::vector<Variant> next;
      for (const Variant& v : combos)
        for (std::size_t i = 0; i < values.size(); ++i) {
          Variant n = v;
          n.axes[key] = values[i];
          next.push_back(n);
        }
      combos = std::move(next);
    }
  }
  std::vector<std::pair<std::string, Variant>> out;
  for (std::size_t c = 0; c < configs.size(); ++c)
    for (const Variant& v : combos) {
      Variant n = v;
      n.config = configs[c].second;
      for (const auto& [key, value] : v.axes.items()) {
        std::size_t i = 0;
        const json& values = block["overrides"][key];
        while (i < values.size() && values[i] != value) ++i;
        apply_override(w, n.config, key, value, fmt::format("{}.overrides.{}[{}]", bpath, key, i));
      }
      try {
        n.config = run_config_to_json(run_config_from_json(n.config, configs[c].first));
      } catch (const ConfigError& e) {
        std::string at = fmt::format("{}.configs[{}]", bpath, c);
        if (!v.axes.empty()) at = fmt::format("{}.overrides ({})", bpath, io::dump_json(v.axes));
        throw ConfigError(e.what(), {w.source, 0, 0, at});
      }
      out.push_back({configs[c].first, n});
    }
  return out;
}

void read_block(const Where& w, const json& block, const std::string& bpath, const fs::path& spec_dir,
                const json& eval, SweepPlan& plan, std::vector<std::string>& override_keys, bool& has_detections,
                std::set<std::string>& seen) {
  if (!block.is_object()) w.fail(bpath, "expected an object with datasets, seeds, configs, overrides, detections");
  static const std::set<std::string> known = {"datasets", "seeds", "configs", "overrides", "detections"};
  for (const auto& [key, value] : block.items())
    if (!known.count(key))
      w.fail(bpath + "." + key, "unknown key (axes are datasets, seeds, configs, overrides, detections)");
  if (!block.contains("datasets")) w.fail(bpath + ".datasets", "missing required key");
  std::vector<std::int64_t> seeds = {1};
  if (block.contains("seeds")) seeds = read_seeds(w, block["seeds"], bpath + ".seeds");
  std::vector<DatasetEntry> datasets;
  const json& ds = nonempty_array(w, block["datasets"], bpath + ".datasets");
  for (std::size_t i = 0; i < ds.size(); ++i)
    datasets.push_back(read_dataset(w, ds[i], fmt::format("{}.datasets[{}]", bpath, i), spec_dir, seeds));
  const auto variants = read_variants(w, block, bpath, spec_dir, override_keys);
  std::vector<std::string> detections = {""};
  if (block.contains("detections")) {
    has_detections = true;
    const json& d = nonempty_array(w, block["detections"], bpath + ".detections");
    detections.clear();
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (!d[i].is_string() || !io::is_plain_name(d[i].get<std::string>()))
        w.fail(fmt::format("{}.detections[{}]", bpath, i),
               "a detection set name (detections/NAME: one folder name, no '/' or '..')");
      detections.push_back(d[i].get<std::string>());
    }
  }
  for (const DatasetEntry& d : datasets) {
    const std::vector<std::optional<std::int64_t>> seed_list = [&] {
      std::vector<std::optional<std::int64_t>> s;
      if (d.seeds.empty()) s.push_back(std::nullopt);
      for (auto v : d.seeds) s.push_back(v);
      return s;
    }();
    for (const auto& seed : seed_list)
      for (const auto& [config_name, variant] : variants)
        for (const std::string& det : detections) {
          SweepJob job;
          json dataset = d.content;
          if (seed) dataset["seed"] = *seed;
          job.content = {{"dataset", dataset},
                         {"config", config_name},
                         {"run_config", variant.config},
                         {"detections", det},
                         {"eval", eval}};
          job.id = io::sha256_hex(io::dump_json(job.content)).substr(0, 16);
          if (!seen.insert(job.id).second) continue;  // the same job from another block
          job.axes = {{"dataset", d.label}, {"seed", seed ? json(*seed) : json(nullptr)}, {"config", config_name}};
          for (const auto& [k, v] : variant.axes.items()) job.axes[k] = v;
          job.axes["detections"] = det;
          plan.jobs.push_back(std::move(job));
        }
  }
}

/// a × b, saturating at the largest value (a spec's counts multiply quickly).
std::uint64_t mul_sat(std::uint64_t a, std::uint64_t b) {
  return b != 0 && a > std::numeric_limits<std::uint64_t>::max() / b ? std::numeric_limits<std::uint64_t>::max()
                                                                      : a * b;
}
std::uint64_t array_size(const json& block, const char* key) {
  return block.is_object() && block.contains(key) && block[key].is_array() ? block[key].size() : 1;
}

/// The number of jobs a block expands to, from the sizes of its axes alone (nothing is expanded), so that a
/// spec of 10⁹ jobs is refused in a few bytes of memory. Malformed axes count 1: read_block refuses them.
std::uint64_t block_job_count(const json& block) {
  if (!block.is_object()) return 1;
  const std::uint64_t seeds = array_size(block, "seeds");
  std::uint64_t datasets = 0;
  if (block.contains("datasets") && block["datasets"].is_array()) {
    for (const json& d : block["datasets"]) {
      if (d.is_object() && d.contains("path")) datasets += 1;
      else if (d.is_object() && d.contains("seeds") && d["seeds"].is_array()) datasets += d["seeds"].size();
      else datasets += seeds;
    }
  }
  std::uint64_t n = mul_sat(std::max<std::uint64_t>(datasets, 1), array_size(block, "configs"));
  if (block.contains("overrides") && block["overrides"].is_object())
    for (const auto& [key, values] : block["overrides"].items())
      n = mul_sat(n, values.is_array() ? values.size() : 1);
  return mul_sat(n, array_size(block, "detections"));
}

void check_job_count(const Where& w, const json& axes, std::size_t max_jobs) {
  std::uint64_t n = 0;
  if (axes.is_array())
    for (const json& b : axes) n = std::min(n + block_job_count(b), std::numeric_limits<std::uint64_t>::max() / 2);
  else
    n = block_job_count(axes);
  if (n > max_jobs)
    w.fail("axes", fmt::format("the spec expands to {} jobs, more than the limit of {} (a sweep that large is "
                               "usually a typo; if it is meant, raise the limit with --max-jobs N)",
                               n >= std::numeric_limits<std::uint64_t>::max() / 2 ? std::string("more than 10^18")
                                                                                   : std::to_string(n),
                               max_jobs));
}

}  // namespace

SweepPlan plan_sweep(const json& spec, const fs::path& spec_dir, const std::string& source, std::size_t max_jobs) {
  const Where w{source};
  if (!spec.is_object()) w.fail("", "a sweep spec is a JSON object");
  static const std::set<std::string> known = {"format", "description", "axes", "eval"};
  for (const auto& [key, value] : spec.items())
    if (!known.count(key)) w.fail(key, "unknown key (a spec has format, description, axes, eval)");
  if (spec.contains("format") && spec["format"] != kSweepSpecFormat)
    w.fail("format", fmt::format("unsupported spec format {} (this roe reads \"{}\")", io::dump_json(spec["format"]),
                                 kSweepSpecFormat));
  if (!spec.contains("format"))
    log::warn("{}: no \"format\" key: read as \"{}\" (write it, so a later roe can tell the version)", source,
              kSweepSpecFormat);
  if (spec.contains("description") && !spec["description"].is_string()) w.fail("description", "expected a string");
  if (!spec.contains("axes")) w.fail("axes", "missing required key");
  check_job_count(w, spec["axes"], max_jobs);
  const json eval = read_eval(w, spec.contains("eval") ? &spec["eval"] : nullptr);
  SweepPlan plan;
  plan.spec = spec;
  std::vector<std::string> override_keys;
  bool has_detections = false;
  std::set<std::string> seen;
  const json& axes = spec["axes"];
  if (axes.is_array()) {
    if (axes.empty()) w.fail("axes", "expected at least one block of axes");
    for (std::size_t b = 0; b < axes.size(); ++b)
      read_block(w, axes[b], fmt::format("axes[{}]", b), spec_dir, eval, plan, override_keys, has_detections, seen);
  } else {
    read_block(w, axes, "axes", spec_dir, eval, plan, override_keys, has_detections, seen);
  }
  plan.axis_names = {"dataset", "seed", "config"};
  for (const auto& k : override_keys) plan.axis_names.push_back(k);
  if (has_detections) plan.axis_names.push_back("detections");
  for (SweepJob& j : plan.jobs) {
    // A block without an override another block has: the config's own value, shown as such.
    for (const auto& k : override_keys)
      if (!j.axes.contains(k)) j.axes[k] = nullptr;
    if (!has_detections) j.axes.erase("detections");
  }
  return plan;
}

std::vector<std::string> keep_indices(SweepPlan& plan, const std::vector<std::string>& existing_ids) {
  std::vector<SweepJob> ordered;
  std::vector<std::string> dropped;
  std::vector<bool> used(plan.jobs.size(), false);
  for (const std::string& id : existing_ids) {
    auto it = std::find_if(plan.jobs.begin(), plan.jobs.end(), [&](const SweepJob& j) { return j.id == id; });
    if (it == plan.jobs.end()) {
      dropped.push_back(id);
      continue;
    }
    used[static_cast<std::size_t>(it - plan.jobs.begin())] = true;
    ordered.push_back(*it);
  }
  for (std::size_t i = 0; i < plan.jobs.size(); ++i)
    if (!used[i]) ordered.push_back(plan.jobs[i]);
  plan.jobs = std::move(ordered);
  return dropped;
}

std::vector<std::size_t> shard_indices(std::size_t n_jobs, std::size_t shard, std::size_t count) {
  ROE_CHECK(count > 0 && shard < count, "shard out of range");
  std::vector<std::size_t> out;
  for (std::size_t k = shard; k < n_jobs; k += count) out.push_back(k);
  return out;
}

std::pair<std::size_t, std::size_t> parse_shard(const std::string& text, const std::string& option) {
  const std::size_t slash = text.find('/');
  const auto digits = [](const std::string& s) {
    return !s.empty() && s.size() <= 9 && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
  };
  if (slash != std::string::npos) {
    const std::string a = text.substr(0, slash), b = text.substr(slash + 1);
    if (digits(a) && digits(b)) {
      const std::size_t i = std::stoul(a), n = std::stoul(b);
      if (n >= 1 && i < n) return {i, n};
    }
  }
  throw InputError(fmt::format("{}: expected i/N with 0 <= i < N (shards are 0-based), got '{}'", option, text),
                   {"roe sweep run"});
}

}  // namespace roe::app
