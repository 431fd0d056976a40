// roe sweep: the spec model and its expansion into jobs with content-derived ids (no file is written here).
#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <set>
#include <unordered_map>
#include <unordered_set>

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

/// The eval options of a sweep's "eval" block (absent: the defaults), every setting of
/// for_each_sweep_eval_setting read strictly and checked by run_eval's own rule.
EvalOptions read_eval(const Where& w, const json* j) {
  EvalOptions o;
  if (j) {
    io::JsonObject r(*j, w.source, "eval");
    for_each_sweep_eval_setting(o, [&](const char* key, auto& value) {
      if (std::string(key) != "t_offset_s") return r.get(key, value);
      const json* v = r.raw(key);
      if (!v || v->is_null()) return;
      try {  // seconds or "auto": its own rule (read_sweep_t_offset)
        read_sweep_t_offset(*v, o);
      } catch (const InputError& err) {
        w.fail(std::string("eval.") + key, err.bare_message());
      }
    });
    r.finish();
  }
  for_each_sweep_eval_setting(o, [&](const char* key, const auto&) {
    try {
      check_sweep_eval_setting(o, key);
    } catch (const InputError& err) {
      w.fail(std::string("eval.") + key, err.bare_message());
    }
  });
  return o;
}

/// A job's "eval" block: every setting written, defaults included (so writing a default changes no id).
json eval_json(const EvalOptions& o) {
  json e = json::object();
  for_each_sweep_eval_setting(o, [&](const char* key, const auto& value) { e[key] = value; });
  e["t_offset_s"] = sweep_t_offset_json(o);
  return e;
}

struct DatasetEntry {
  json label;                   ///< axis value: the preset name or the path as written
  store::SweepDataset content;  ///< the job's "dataset" without the seed
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
    d.content.preset = preset;
    d.content.preset_sha256 = io::sha256_hex(preset_text(preset));
    d.content.duration_s = duration;
    if (d.seeds.empty()) d.seeds = block_seeds;
    return d;
  }
  if (!d.seeds.empty()) w.fail(path + ".seeds", "seeds apply to simulator presets, not to a dataset folder");
  if (duration) w.fail(path + ".duration_s", "duration_s applies to simulator presets, not to a dataset folder");
  const fs::path p = fs::path(dir).is_absolute() ? fs::path(dir) : spec_dir / dir;
  if (!fs::is_regular_file(store::manifest_path(p)))
    w.fail(path + ".path", fmt::format("not a dataset folder (no roe.json): {}", p.string()));
  d.label = dir;
  d.content.path = io::provenance_path(p);
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

/// The configs × override values of one block, and its datasets and detection sets: what a job of the block is
/// made from. A variant is an index: config (v / n_combos), then one value per override key, mixed-radix with
/// the last key varying fastest (the cross product in key order).
struct Block {
  std::string bpath;
  std::vector<std::pair<std::string, json>> configs;  ///< label, JSON as read
  std::vector<std::string> keys;                      ///< override keys, in the spec's order
  json overrides = json::object();                    ///< key -> values
  std::size_t n_combos = 1;
  std::vector<DatasetEntry> datasets;
  std::vector<std::string> detections = {""};
  std::size_t n_variants() const { return configs.size() * n_combos; }
  /// The value index of each override key in combination `combo`.
  std::vector<std::size_t> picks(std::size_t combo) const {
    std::vector<std::size_t> pick(keys.size());
    for (std::size_t k = keys.size(); k-- > 0;) {
      pick[k] = combo % overrides[keys[k]].size();
      combo /= overrides[keys[k]].size();
    }
    return pick;
  }
  /// The override key -> value of combination `combo`.
  json combo_axes(std::size_t combo) const {
    json axes = json::object();
    const auto pick = picks(combo);
    for (std::size_t k = 0; k < keys.size(); ++k) axes[keys[k]] = overrides[keys[k]][pick[k]];
    return axes;
  }
  /// Variant `v`'s run config, validated by the run config loader.
  RunConfig variant_config(const Where& w, std::size_t v) const {
    const std::size_t c = v / n_combos, combo = v % n_combos;
    json config = configs[c].second;
    const auto pick = picks(combo);
    for (std::size_t k = 0; k < keys.size(); ++k)
      apply_override(w, config, keys[k], overrides[keys[k]][pick[k]],
                     fmt::format("{}.overrides.{}[{}]", bpath, keys[k], pick[k]));
    try {
      return run_config_from_json(config, configs[c].first);
    } catch (const ConfigError& e) {
      std::string at = fmt::format("{}.configs[{}]", bpath, c);
      if (!keys.empty()) at = fmt::format("{}.overrides ({})", bpath, io::dump_json(combo_axes(combo)));
      throw ConfigError(e.what(), {w.source, 0, 0, at});
    }
  }
};

void read_variants(const Where& w, const json& block, const fs::path& spec_dir, std::vector<std::string>& override_keys,
                   Block& b) {
  if (block.contains("configs")) {
    const json& c = nonempty_array(w, block["configs"], b.bpath + ".configs");
    for (std::size_t i = 0; i < c.size(); ++i)
      b.configs.push_back(read_config(w, c[i], fmt::format("{}.configs[{}]", b.bpath, i), spec_dir));
  } else {
    b.configs.push_back(read_config(w, "default", b.bpath + ".configs", spec_dir));
  }
  if (!block.contains("overrides")) return;
  const json& o = block["overrides"];
  if (!o.is_object()) w.fail(b.bpath + ".overrides", "expected an object {\"filter.KEY\": [values]}");
  for (const auto& [key, values] : o.items()) {
    nonempty_array(w, values, fmt::format("{}.overrides.{}", b.bpath, key));
    if (std::find(override_keys.begin(), override_keys.end(), key) == override_keys.end())
      override_keys.push_back(key);
    b.keys.push_back(key);
    b.overrides[key] = values;
    b.n_combos *= values.size();  // bounded: check_job_count refused a spec of more jobs first
  }
}

void read_block(const Where& w, const json& block, const std::string& bpath, const fs::path& spec_dir,
                std::vector<std::string>& override_keys, bool& has_detections, Block& b) {
  if (!block.is_object()) w.fail(bpath, "expected an object with datasets, seeds, configs, overrides, detections");
  static const std::set<std::string> known = {"datasets", "seeds", "configs", "overrides", "detections"};
  for (const auto& [key, value] : block.items())
    if (!known.count(key))
      w.fail(bpath + "." + key, "unknown key (axes are datasets, seeds, configs, overrides, detections)");
  if (!block.contains("datasets")) w.fail(bpath + ".datasets", "missing required key");
  b.bpath = bpath;
  std::vector<std::int64_t> seeds = {1};
  if (block.contains("seeds")) seeds = read_seeds(w, block["seeds"], bpath + ".seeds");
  const json& ds = nonempty_array(w, block["datasets"], bpath + ".datasets");
  for (std::size_t i = 0; i < ds.size(); ++i)
    b.datasets.push_back(read_dataset(w, ds[i], fmt::format("{}.datasets[{}]", bpath, i), spec_dir, seeds));
  read_variants(w, block, spec_dir, override_keys, b);
  if (block.contains("detections")) {
    has_detections = true;
    const json& d = nonempty_array(w, block["detections"], bpath + ".detections");
    b.detections.clear();
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (!d[i].is_string() || !io::is_plain_name(d[i].get<std::string>()))
        w.fail(fmt::format("{}.detections[{}]", bpath, i),
               "a detection set name (detections/NAME: one folder name, no '/' or '..')");
      b.detections.push_back(d[i].get<std::string>());
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

struct SweepPlan::Expansion {
  std::string source;
  std::vector<Block> blocks;
  json eval;  ///< every job's eval block (eval_json)
  std::vector<std::string> override_keys;
  bool has_detections = false;

  /// The job of recipe `r`, whose variant's run config is `config` (variant_config of its block).
  SweepJob make(const Recipe& r, const RunConfig& config) const {
    const Block& b = blocks[r.block];
    const DatasetEntry& d = b.datasets[r.dataset];
    const std::string& det = b.detections[r.detections];
    const std::string& config_name = b.configs[r.variant / b.n_combos].first;
    SweepJob job;
    job.content.dataset = d.content;
    if (r.has_seed) job.content.dataset.seed = r.seed;
    job.content.config = config_name;
    job.content.run_config = config;
    job.content.detections = det;
    job.content.eval = eval;
    job.id = store::sweep_job_id(job.content);
    job.axes = {{"dataset", d.label}, {"seed", r.has_seed ? json(r.seed) : json(nullptr)}, {"config", config_name}};
    const json combo = b.combo_axes(r.variant % b.n_combos);
    for (const auto& [k, v] : combo.items()) job.axes[k] = v;
    // A block without an override another block has: the config's own value, shown as such.
    for (const auto& k : override_keys)
      if (!job.axes.contains(k)) job.axes[k] = nullptr;
    if (has_detections) job.axes["detections"] = det;
    return job;
  }

  /// The recipes of block `bi` in job order (datasets, seeds, variants, detection sets) with their ids. Each
  /// variant's run config is made (and validated) once here and dropped after its jobs' ids.
  void expand(std::uint32_t bi, std::vector<Recipe>& recipes, std::vector<std::string>& ids) const {
    const Where w{source};
    const Block& b = blocks[bi];
    std::vector<Recipe> rs;
    for (std::uint32_t di = 0; di < b.datasets.size(); ++di) {
      const auto& seeds = b.datasets[di].seeds;
      for (std::size_t si = 0; si < std::max<std::size_t>(1, seeds.size()); ++si)
        for (std::uint32_t v = 0; v < b.n_variants(); ++v)
          for (std::uint32_t k = 0; k < b.detections.size(); ++k)
            rs.push_back({bi, di, v, k, seeds.empty() ? 0 : seeds[si], !seeds.empty()});
    }
    std::vector<std::string> rs_ids(rs.size());
    const std::size_t per_variant = b.detections.size(), stride = b.n_variants() * per_variant;
    for (std::uint32_t v = 0; v < b.n_variants(); ++v) {
      const RunConfig config = b.variant_config(w, v);
      for (std::size_t base = v * per_variant; base < rs.size(); base += stride)
        for (std::size_t k = 0; k < per_variant; ++k) rs_ids[base + k] = make(rs[base + k], config).id;
    }
    recipes.insert(recipes.end(), rs.begin(), rs.end());
    ids.insert(ids.end(), rs_ids.begin(), rs_ids.end());
  }
};

SweepJob SweepPlan::job(std::size_t i) const {
  const Recipe& r = recipes.at(i);
  return expansion->make(r, expansion->blocks[r.block].variant_config(Where{expansion->source}, r.variant));
}

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
  auto ex = std::make_shared<SweepPlan::Expansion>();
  ex->source = source;
  ex->eval = eval_json(read_eval(w, spec.contains("eval") ? &spec["eval"] : nullptr));
  const json& axes = spec["axes"];
  if (axes.is_array() && axes.empty()) w.fail("axes", "expected at least one block of axes");
  const std::size_t n_blocks = axes.is_array() ? axes.size() : 1;
  for (std::size_t b = 0; b < n_blocks; ++b) {
    ex->blocks.emplace_back();
    read_block(w, axes.is_array() ? axes[b] : axes, axes.is_array() ? fmt::format("axes[{}]", b) : "axes", spec_dir,
               ex->override_keys, ex->has_detections, ex->blocks.back());
  }
  SweepPlan plan;
  plan.spec = spec;
  std::vector<SweepPlan::Recipe> recipes;
  std::vector<std::string> ids;
  for (std::uint32_t b = 0; b < ex->blocks.size(); ++b) ex->expand(b, recipes, ids);
  std::unordered_set<std::string> seen;  // the same job from another block (or twice in one) is planned once
  for (std::size_t k = 0; k < ids.size(); ++k) {
    if (!seen.insert(ids[k]).second) continue;
    plan.ids.push_back(std::move(ids[k]));
    plan.recipes.push_back(recipes[k]);
  }
  plan.axis_names = {"dataset", "seed", "config"};
  for (const auto& k : ex->override_keys) plan.axis_names.push_back(k);
  if (ex->has_detections) plan.axis_names.push_back("detections");
  plan.expansion = std::move(ex);
  return plan;
}

SweepPlan plan_sweep_file(const fs::path& spec, std::size_t max_jobs) {
  const std::string text = io::read_file(spec), source = spec.string();
  return io::with_json_locations(text, source, [&] {
    return plan_sweep(io::parse_json_text(text, source), spec.parent_path(), source, max_jobs);
  });
}

EvalOptions sweep_eval_options(const json& block, const std::string& source) {
  return read_eval(Where{source}, &block);
}

std::vector<std::string> keep_indices(SweepPlan& plan, const std::vector<std::string>& existing_ids) {
  std::unordered_map<std::string, std::size_t> at;
  for (std::size_t i = 0; i < plan.ids.size(); ++i) at.emplace(plan.ids[i], i);
  std::vector<std::string> ids, dropped;
  std::vector<SweepPlan::Recipe> recipes;
  std::vector<bool> used(plan.ids.size(), false);
  for (const std::string& id : existing_ids) {
    const auto it = at.find(id);
    if (it == at.end()) {
      dropped.push_back(id);
      continue;
    }
    used[it->second] = true;
    ids.push_back(id);
    recipes.push_back(plan.recipes[it->second]);
  }
  for (std::size_t i = 0; i < plan.ids.size(); ++i)
    if (!used[i]) {
      ids.push_back(plan.ids[i]);
      recipes.push_back(plan.recipes[i]);
    }
  plan.ids = std::move(ids);
  plan.recipes = std::move(recipes);
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
