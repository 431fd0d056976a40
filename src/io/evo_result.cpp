#include "roe/io/evo_result.hpp"

#include "roe/core/error.hpp"
#include "roe/io/input.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/io/zip.hpp"

namespace roe::io {
namespace fs = std::filesystem;
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

nlohmann::json object_member(const ZipMember& m, const std::string& source) {
  const std::string where = source + ":" + m.name;
  nlohmann::json j = parse_json_text(m.data, where);
  if (!j.is_object()) throw InputError("is not a JSON object", {where});
  return j;
}

}  // namespace

const NpyArray* EvoResult::array(const std::string& name) const {
  for (const auto& [n, a] : arrays)
    if (n == name) return &a;
  return nullptr;
}

bool looks_like_zip(const fs::path& file) { return read_file_head(file, 4) == std::string("PK\x03\x04", 4); }

EvoResult read_evo_result(const fs::path& zip) {
  const std::string source = zip.string();
  const std::vector<ZipMember> members = read_zip(read_file(zip), source);
  EvoResult r;
  bool info = false, stats = false;
  for (const auto& m : members) {
    if (m.name == "info.json") {
      r.info = object_member(m, source);
      info = true;
    } else if (m.name == "stats.json") {
      r.stats = object_member(m, source);
      for (const auto& [k, v] : r.stats.items())
        if (!v.is_number()) throw InputError("statistic is not a number", {source + ":stats.json", 0, 0, k});
      stats = true;
    } else if (ends_with(m.name, ".npy") || ends_with(m.name, ".npz")) {
      r.arrays.emplace_back(m.name.substr(0, m.name.size() - 4), parse_npy(m.data, source + ":" + m.name));
    } else if (ends_with(m.name, ".tum") || ends_with(m.name, ".kitti")) {
      r.trajectories.emplace_back(m.name, m.data);
    }
  }
  if (!info || !stats)
    throw InputError(std::string("not an evo result file: it has no ") + (info ? "stats.json" : "info.json") +
                         " (evo_ape/evo_rpe --save_results write both)",
                     {source});
  return r;
}

void write_evo_result(const fs::path& zip, const EvoResult& r) {
  std::vector<ZipMember> members;
  members.push_back({"info.json", dump_json(r.info)});
  members.push_back({"stats.json", dump_json(r.stats)});
  for (const auto& [name, a] : r.arrays) members.push_back({name + ".npy", encode_npy(a)});
  for (const auto& [name, text] : r.trajectories) members.push_back({name, text});
  write_file_atomic(zip, write_zip(members));
}

}  // namespace roe::io
