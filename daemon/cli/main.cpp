#include <iostream>

#include "cli/commands.h"
#include "meshio/mesh.h"
#include "service/memory.h"

int main(int argc, char** argv) {
  mm::service::reuse_freed_memory();
  CLI::App app{"meshmark: compress CAD meshes, watermark them per customer, trace leaked copies"};
  app.require_subcommand(1);
  mm::cli::add_offline_commands(app);
  mm::cli::add_compress_commands(app);
  mm::cli::add_run_commands(app);
  mm::cli::add_store_commands(app);
  mm::cli::add_evidence_commands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 64;
  } catch (const mm::InputError& e) {
    std::cerr << "meshmark: error: " << e.what() << "\n";
    return 2;
  } catch (const mm::cli::CommandFailed& e) {
    std::cerr << "meshmark: " << e.what() << "\n";
    return e.code;
  } catch (const std::exception& e) {
    std::cerr << "meshmark: internal error: " << e.what() << "\n";
    return 3;
  }
  return 0;
}
