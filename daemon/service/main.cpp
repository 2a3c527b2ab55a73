// meshmarkd: the resident batch daemon. See docs/daemon.md and config/config-keys.md.
#include <CLI/CLI.hpp>
#include <cstdlib>
#include <iostream>
#include <spdlog/spdlog.h>

#include "service/config.h"
#include "service/daemon.h"
#include "service/memory.h"
#include "store/home.h"

int main(int argc, char** argv) {
  mm::service::reuse_freed_memory();
  CLI::App app{"meshmarkd: watches drop folders and runs protect/detect jobs from the meshmark store"};
  std::string config_path;
  bool check_only = false, init_home = false;
  app.add_option("-c,--config", config_path, "configuration file (JSON; see config/config-keys.md)")
      ->envname("MESHMARKD_CONFIG")
      ->required();
  app.add_flag("--check-config", check_only, "validate the configuration and exit");
  app.add_flag("--init-home", init_home, "create the home (database, master key) if it does not exist");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 64;
  }
  mm::service::Config cfg;
  try {
    cfg = mm::service::load_config(config_path);
  } catch (const mm::service::ConfigError& e) {
    std::cerr << "meshmarkd: " << e.what() << "\n";
    return 78;  // EX_CONFIG
  }
  if (check_only) {
    std::cout << config_path << ": ok\n";
    return 0;
  }
  try {
    mm::service::setup_logging(cfg);
    if (init_home) {
      auto home = mm::store::resolve_home(cfg.home);
      home.master_key = cfg.master_key_path();
      if (mm::store::init_home(home)) spdlog::info("initialised home {}", home.root);
    }
    mm::service::Daemon d(cfg);
    return d.run();
  } catch (const std::exception& e) {
    spdlog::critical("meshmarkd: {}", e.what());
    std::cerr << "meshmarkd: " << e.what() << "\n";
    return 1;
  }
}
