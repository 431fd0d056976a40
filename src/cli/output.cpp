#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>

#include "roe/io/json.hpp"
#include "command.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace roe::cli {

CLI::Validator number_in(const std::string& kind) {
  std::string shown = kind == "positive"       ? "NUMBER>0"
                      : kind == "non-negative" ? "NUMBER>=0"
                      : kind == "integer>=1"   ? "INT>=1"
                      : kind == "integer>=0"   ? "INT>=0"
                      : kind == "fraction"     ? "FLOAT in (0, 1]"
                      : kind == "confidence"   ? "FLOAT in (0.5, 1)"
                                               : throw std::logic_error("number_in: unknown kind " + kind);
  return CLI::Validator(
      [kind](std::string& s) {
        std::size_t used = 0;
        double v = 0.0;
        try {
          v = std::stod(s, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        bool ok = used > 0 && used == s.size() && std::isfinite(v);
        // Integers: digits only (no 2.0, no 1e20) and within int.
        const bool digits = !s.empty() && s.size() <= 9 &&
                            std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
        std::string want;
        if (kind == "positive") ok = ok && v > 0, want = "a positive number";
        else if (kind == "non-negative") ok = ok && v >= 0, want = "a number >= 0";
        else if (kind == "integer>=1") ok = digits && v >= 1, want = "an integer >= 1";
        else if (kind == "integer>=0") ok = digits, want = "an integer >= 0";
        else if (kind == "fraction") ok = ok && v > 0 && v <= 1, want = "a number in (0, 1]";
        else ok = ok && v > 0.5 && v < 1, want = "a number in (0.5, 1)";
        return ok ? std::string() : "must be " + want + ", got '" + s + "'";
      },
      shown);
}
namespace {
double now_s() {
  using namespace std::chrono;
  return duration<double>(steady_clock::now().time_since_epoch()).count();
}
}  // namespace

void emit(const nlohmann::json& summary, const std::string& human, bool listing) {
  if (globals().json) {
    nlohmann::json j = summary;
    if (j.is_object()) {
      if (!j.contains("command")) j["command"] = globals().command;
      if (!j.contains("out")) {
        nlohmann::json out = nullptr;
        for (const char* k : {"dataset", "output"})
          if (j.contains(k) && j[k].is_string()) {
            out = j[k];
            break;
          }
        if (out.is_null() && j.contains("outputs") && j["outputs"].is_object() && j["outputs"].contains("dir"))
          out = j["outputs"]["dir"];
        j["out"] = out;
      }
      if (!j.contains("warnings")) j["warnings"] = nlohmann::json::array();
    }
    std::cout << roe::io::dump_json(j, 2) << "\n";
  } else if ((listing || !globals().quiet) && !human.empty()) {
    std::cout << human;
    if (human.back() != '\n') std::cout << "\n";
  }
  std::cout.flush();
}

Progress::Progress(std::string label, std::size_t total)
    : label_(std::move(label)),
      total_(total),
      enabled_(!globals().quiet && isatty(STDERR_FILENO) != 0),
      start_s_(now_s()) {}

Progress::~Progress() { finish(); }

void Progress::update(std::size_t done) {
  if (!enabled_ || finished_) return;
  const double t = now_s();
  if (done < total_ && t - last_draw_s_ < 0.1) return;
  last_draw_s_ = t;
  const double frac = total_ ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
  const int width = 30;
  const int filled = static_cast<int>(frac * width);
  const double elapsed = t - start_s_;
  const double eta = frac > 1e-6 ? elapsed * (1.0 - frac) / frac : 0.0;
  std::fprintf(stderr, "\r%s [%.*s%*s] %zu/%zu ETA %.0fs ", label_.c_str(), filled,
               "##############################", width - filled, "", done, total_, eta);
  std::fflush(stderr);
}

void Progress::finish() {
  if (!enabled_ || finished_) return;
  finished_ = true;
  if (last_draw_s_ >= 0.0) std::fprintf(stderr, "\n");
}

std::function<void(std::size_t, std::size_t)> Progress::callback() {
  return [this](std::size_t done, std::size_t total) {
    total_ = total;
    update(done);
  };
}

}  // namespace roe::cli
