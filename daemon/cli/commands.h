// Each group of `meshmark` subcommands registers itself on the app. A command reports failure by
// throwing: mm::InputError (bad input file or stream) -> exit 2, CommandFailed -> its own code,
// anything else -> exit 3. Usage errors exit 64. See docs/cli.md.
#pragma once
#include <CLI/CLI.hpp>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

namespace mm::cli {

struct CommandFailed : std::runtime_error {
  CommandFailed(int exit_code, const std::string& what) : std::runtime_error(what), code(exit_code) {}
  int code;
};

// For every floating-point option: CLI11's Range lets NaN through (every comparison with it is
// false), and "nan" or "inf" parse as numbers, so without this they reached the commands
// (`compress --tolerance nan` was an internal error, exit 3). A usage error instead (exit 64).
inline const CLI::Validator kFiniteNumber(
    [](std::string& value) -> std::string {
      try {
        if (!std::isfinite(std::stod(value))) return "value " + value + " is not a finite number";
      } catch (const std::exception&) {
        // Not a number at all: the option's own conversion reports it.
      }
      return {};
    },
    "FINITE");

// Runs f; store and key failures (missing home, unprotected master key, unknown name) are the
// user's to fix: they become CommandFailed(1) with their message, not internal errors.
void refusing_store_errors(const std::function<void()>& f);

void add_offline_commands(CLI::App& app);  // info, sample, keygen, attack, embed, extract
void add_mark_commands(CLI::App& app);     // embed, extract (called by add_offline_commands)
void add_attack_commands(CLI::App& app);   // attack ... (called by add_offline_commands)
void add_compress_commands(CLI::App& app);  // compress, decompress, compare, render
void add_run_commands(CLI::App& app);      // submit protect|detect, run --until-empty
void add_store_commands(CLI::App& app);
void add_evidence_commands(CLI::App& app);  // evidence DETECTION OUT_DIR | pubkey, verify PACKAGE    // init, customer, jobs, assets, copies, detections

}  // namespace mm::cli
