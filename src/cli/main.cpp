// roe: command-line entry point. Builds the CLI11 tree from the self-registered commands, parses,
// runs the selected command and maps errors to the exit codes of DESIGN §1.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "command.hpp"
#include "roe/io/json.hpp"
#include "roe/io/output.hpp"
#include "roe/core/error.hpp"
#include "roe/core/log.hpp"
#include "roe/version.hpp"

namespace roe::cli {
namespace {

struct Entry {
  std::string parent, name, description;
  int order;
  SetupFn setup;
};

std::vector<Entry>& registry() {
  static std::vector<Entry> entries;
  return entries;
}

GlobalOptions g_globals;

}  // namespace

const GlobalOptions& globals() { return g_globals; }

Registrar::Registrar(const char* parent, const char* name, const char* description, int order,
                     SetupFn setup) {
  registry().push_back({parent, name, description, order, setup});
}

bool runs_here(const char* parent, const char* name) {
  for (const Entry& e : registry())
    if (e.parent == parent && e.name == name) return true;
  return false;
}

namespace {
/// With --json every failure is one JSON document on stdout as well (the message still goes to stderr):
/// `command`, `error` (message, and file/line/column/key when known), `exit_code`.
bool g_json_errors = false;
int fail(int code, const std::string& command, const std::string& prefix, const std::string& message,
         const roe::ErrorContext* where = nullptr, const std::string& bare = {}) {
  std::cerr << "roe: " << prefix << message << "\n";
  if (!g_json_errors) return code;
  nlohmann::json err = {{"message", bare.empty() ? message : bare}};
  if (where) {
    if (!where->file.empty()) err["file"] = where->file;
    if (where->line > 0) err["line"] = where->line;
    if (where->column > 0) err["column"] = where->column;
    if (!where->key.empty()) err["key"] = where->key;
  }
  std::cout << roe::io::dump_json({{"command", command}, {"error", err}, {"exit_code", code}}, 2) << std::endl;
  return code;
}
}  // namespace

}  // namespace roe::cli

/// CLI11 lists the arguments it did not expect last one first; the user typed them in argv's order.
static std::string extras_in_order(const std::string& what, int argc, char** argv) {
  const std::string::size_type colon = what.find(": ");
  if (colon == std::string::npos) return what;
  std::vector<std::string> extras;
  std::istringstream words(what.substr(colon + 2));
  for (std::string w; words >> w;) extras.push_back(w);
  std::vector<std::string> ordered;
  for (int i = 1; i < argc; ++i) {
    const auto it = std::find(extras.begin(), extras.end(), std::string(argv[i]));
    if (it == extras.end()) continue;
    ordered.push_back(*it);
    extras.erase(it);
  }
  ordered.insert(ordered.end(), extras.begin(), extras.end());  // anything not found as typed
  std::string out = what.substr(0, colon + 2);
  for (std::size_t i = 0; i < ordered.size(); ++i) out += (i ? " " : "") + ordered[i];
  return out;
}

namespace {
using namespace roe::cli;

/// The command tree from the self-registered commands (sorted by their order, then name), with each
/// leaf's run function.
std::map<CLI::App*, RunFn> register_commands(CLI::App& app) {
  std::vector<Entry> entries = registry();
  // The forwarded commands this executable does not run itself: listed, handed to their helper (forward.cpp).
  for (const ForwardedCommand& c : kForwardedCommands)
    if (!runs_here(c.parent, c.name)) entries.push_back({c.parent, c.name, c.description, c.order, &setup_forwarded});
  std::stable_sort(entries.begin(), entries.end(),
                   [](const Entry& a, const Entry& b) {  // ties by name: independent of the link order
                     return a.order != b.order ? a.order < b.order : a.name < b.name;
                   });
  std::map<CLI::App*, RunFn> runs;
  std::map<std::string, CLI::App*> groups;
  for (const auto& e : entries) {
    CLI::App* parent = &app;
    if (!e.parent.empty()) {
      auto it = groups.find(e.parent);
      if (it == groups.end()) {
        CLI::App* g = app.add_subcommand(e.parent, e.parent == "sweep" ? "Plan, run (any scheduler), check and aggregate sweeps of runs" : "Import recordings, calibrations and detections into a dataset folder");
        g->require_subcommand(1);
        g->fallthrough();
        it = groups.emplace(e.parent, g).first;
      }
      parent = it->second;
    }
    CLI::App* sub = parent->add_subcommand(e.name, e.description);
    sub->fallthrough();
    runs[sub] = e.setup(*sub);
  }
  return runs;
}

/// The first word is the command: one that is none is named as such, before any option of a later
/// command is read (`roe seq4 run` is an unknown command, not `roe run` without a dataset). Returns the
/// exit code of that error, or −1 when the first word is a command.
int refuse_unknown_first_word(CLI::App& app, int argc, char** argv) {
  std::string names;
  for (const CLI::App* c : app.get_subcommands({})) names += (names.empty() ? "" : ", ") + c->get_name();
  const auto is_command = [&](const std::string& w) {
    for (const CLI::App* c : app.get_subcommands({}))
      if (c->get_name() == w) return true;
    return false;
  };
  for (int i = 1; i < argc && std::string(argv[i]) != "--"; ++i) {
    const std::string w = argv[i];
    if (w.empty() || w[0] == '-') continue;
    if (is_command(w)) break;
    std::string swap;
    if (i + 1 < argc && is_command(argv[i + 1]))
      swap = fmt::format(" (did you mean `roe {} {}`?)", argv[i + 1], w);
    return fail(2, "", "error: ", fmt::format("unknown command '{}'{} (commands: {})\n(see roe --help)", w, swap, names));
  }
  return -1;
}

/// Bad usage (CLI11's parse errors): the same "roe: error:" prefix as every other error, where to read
/// about the command, exit code 2 (DESIGN §1); --help and --version exit 0.
int usage_error(CLI::App& app, const CLI::ParseError& e, int argc, char** argv) {
  if (g_json_errors && dynamic_cast<const CLI::CallForVersion*>(&e)) {
    std::cout << roe::io::dump_json({{"command", "version"},
                                     {"version", roe::kVersion},
                                     {"features", features_json()},
                                     {"exit_code", 0}},
                                    2)
              << std::endl;
    return 0;
  }
  if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
  // Bad usage: the same "roe: error:" prefix as every other error, and where to read about the command.
  std::string path = "roe";
  CLI::App* level = &app;
  while (!level->get_subcommands().empty()) {
    level = level->get_subcommands().front();
    path += " " + level->get_name();
  }
  // "A subcommand is required" after a word that is none: name the word and the commands.
  if (dynamic_cast<const CLI::RequiredError*>(&e) && !level->get_subcommands({}).empty()) {
    std::string names;
    for (const CLI::App* c : level->get_subcommands({})) names += (names.empty() ? "" : ", ") + c->get_name();
    std::string word;
    bool after = level == &app;
    for (int i = 1; i < argc; ++i) {
      const std::string t = argv[i];
      if (!after) {
        after = t == level->get_name();
        continue;
      }
      if (!t.empty() && t[0] != '-') {
        word = t;
        break;
      }
    }
    return fail(2, path.substr(std::min<std::size_t>(path.size(), 4)), "error: ",
                (word.empty() ? "a command is required" : "unknown command '" + word + "'") + " (" +
                    (level == &app ? "commands" : "subcommands of " + path.substr(4)) + ": " + names +
                    ")\n(see " + path + " --help)");
  }
  // An unknown option before the command's name is a global one: point to `roe --help`, not to the
  // command's help (`roe --bogus run ...`).
  if (dynamic_cast<const CLI::ExtrasError*>(&e) && level != &app) {
    const std::string first = app.get_subcommands().front()->get_name();
    const auto known = [&](const std::string& name) { return app.get_option_no_throw(name) != nullptr; };
    for (int i = 1; i < argc && argv[i] != first; ++i) {
      const std::string t = argv[i];
      if (t.size() < 2 || t[0] != '-' || t == "--") continue;
      bool ok = true;
      if (t[1] == '-') {
        ok = known(t.substr(0, t.find('=')));
      } else {
        for (std::size_t k = 1; k < t.size() && ok; ++k) ok = known(std::string("-") + t[k]);
      }
      if (!ok) {
        path = "roe";
        break;
      }
    }
  }
  // DESIGN §1: bad usage is exit code 2
  const std::string what = dynamic_cast<const CLI::ExtrasError*>(&e) ? extras_in_order(e.what(), argc, argv)
                                                                       : std::string(e.what());
  return fail(2, path.substr(std::min<std::size_t>(path.size(), 4)), "error: ",
              what + "\n(see " + path + " --help)", nullptr, what.c_str());
}

/// Runs the selected leaf command and maps its errors to the exit codes of DESIGN §1.
int run_command(CLI::App& app, const std::map<CLI::App*, RunFn>& runs) {
  // Find the selected leaf command.
  CLI::App* leaf = &app;
  while (!leaf->get_subcommands().empty()) {
    leaf = leaf->get_subcommands().front();
    g_globals.command += (g_globals.command.empty() ? "" : " ") + leaf->get_name();
  }
  auto it = runs.find(leaf);
  if (it == runs.end()) {
    return fail(2, "", "", "no command given (see roe --help)");
  }
  try {
    return it->second();
  } catch (const roe::InputError& e) {
    return fail(2, g_globals.command, "error: ", e.what(), &e.context(), e.bare_message());
  } catch (const roe::DataError& e) {
    return fail(1, g_globals.command, "error: ", e.what(), &e.context(), e.bare_message());
  } catch (const roe::Error& e) {
    return fail(3, g_globals.command, "internal error: ", e.what(), &e.context(), e.bare_message());
  } catch (const std::exception& e) {
    return fail(3, g_globals.command, "internal error: ", e.what());
  }
}

}  // namespace

int main(int argc, char** argv) {
  using namespace roe::cli;
  for (int i = 1; i < argc && std::string(argv[i]) != "--"; ++i) g_json_errors |= std::string(argv[i]) == "--json";
  // Before anything else (signal handlers included: exec keeps only ignored signals ignored).
  std::string forward_error;
  int forward_code = 3;
  if (const ForwardedCommand* c = forward_to_helper(argc, argv, forward_error, forward_code)) {
    if (forward_error.empty()) return 0;  // its --help, answered by roe itself (no helper to ask)
    return fail(forward_code, std::string(c->parent[0] ? std::string(c->parent) + " " : "") + c->name, "error: ",
                forward_error);
  }
  g_globals.argc = argc;
  g_globals.argv = argv;
  roe::io::remove_temporaries_on_signals();
  CLI::App app{"roe: AI-based, object-relative visual-inertial state estimation (offline toolkit)",
               "roe"};
  app.require_subcommand(1);
  app.fallthrough();  // global flags may follow the subcommand
  app.set_version_flag("--version", version_text());
  app.add_flag("-q,--quiet", g_globals.quiet, "No progress bars and no human summary on stdout");
  app.add_flag("-v,--verbose", g_globals.verbose, "More logging on stderr (repeat for debug)");
  app.add_flag("--json", g_globals.json, "Print one JSON document with the command's summary on stdout");
  app.add_flag("--force", g_globals.force, "Allow replacing an existing, non-empty output");
  const std::map<CLI::App*, RunFn> runs = register_commands(app);
  if (const int code = refuse_unknown_first_word(app, argc, argv); code >= 0) return code;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return usage_error(app, e, argc, argv);
  }
  roe::log::set_level(g_globals.quiet          ? roe::log::Level::kWarn
                      : g_globals.verbose >= 2 ? roe::log::Level::kDebug
                      : g_globals.verbose == 1 ? roe::log::Level::kInfo
                                               : roe::log::Level::kWarn);
  return run_command(app, runs);
}
