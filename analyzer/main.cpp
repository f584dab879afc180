// inertia-analyze: one binary, several verbs (docs/design.md, "Command line").
// Exit status: 0 success, 2 bad input (InputError, CLI misuse), 1 anything else.
#include <CLI/CLI.hpp>
#include <malloc.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string_view>
#include <charconv>
#include <cmath>
#include <map>
#include <vector>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>

#include "analyzer/commands/characterize.hpp"
#include "analyzer/commands/compensate.hpp"
#include "analyzer/commands/export.hpp"
#include "analyzer/commands/sheet.hpp"
#include "analyzer/commands/unit.hpp"
#include "analyzer/commands/record.hpp"
#include "analyzer/commands/plan_check.hpp"
#include "analyzer/commands/diagnose.hpp"
#include "analyzer/commands/noise.hpp"
#include "analyzer/commands/online.hpp"
#include "analyzer/commands/reproduce_paper.hpp"
#include "analyzer/commands/simulate_model.hpp"
#include "common/input_error.hpp"
#include "common/parallel.hpp"
#include "hal/sim/simulate.hpp"

namespace {

/// "CASE=WEIGHT" pairs; a malformed one is bad input.
std::map<std::string, double> parse_weights(const std::vector<std::string>& pairs) {
  std::map<std::string, double> weights;
  for (const std::string& pair : pairs) {
    const auto eq = pair.find('=');
    double w = 0.0;
    const char* begin = pair.data() + (eq == std::string::npos ? 0 : eq + 1);
    const auto [end, ec] = std::from_chars(begin, pair.data() + pair.size(), w);
    if (eq == std::string::npos || eq == 0 || ec != std::errc() || end != pair.data() + pair.size() || !(w > 0.0) ||
        !std::isfinite(w)) {
      throw inertia::InputError("--weight '" + pair + "': expected CASE=WEIGHT with a positive weight");
    }
    weights[pair.substr(0, eq)] = w;
  }
  return weights;
}

/// --model values of `online` and `simulate`: "SENSOR=FILE" or "FILE" (the bench's only sensor).
std::map<std::string, std::filesystem::path> parse_models(const std::vector<std::string>& values) {
  std::map<std::string, std::filesystem::path> models;
  for (const std::string& v : values) {
    const auto eq = v.find('=');
    const bool named = eq != std::string::npos && v.substr(0, eq).find('/') == std::string::npos;
    const std::string sensor = named ? v.substr(0, eq) : std::string();
    const std::string file = named ? v.substr(eq + 1) : v;
    if (file.empty() || (named && sensor.empty())) throw inertia::InputError("--model '" + v + "': expected [SENSOR=]MODEL.toml");
    if (!models.emplace(sensor, file).second) throw inertia::InputError("--model '" + v + "': sensor given twice");
  }
  return models;
}

int run(int argc, char** argv) {
  CLI::App app{"inertia-analyze: identify nonlinear dynamic models of inertial sensors"};
  app.require_subcommand(1);

  inertia::commands::SimulateOptions simulate_options;
  std::vector<std::string> simulate_models;
  auto* simulate = app.add_subcommand("simulate", "simulate a bench's test plan into a dataset folder");
  simulate->add_option("--bench", simulate_options.bench, "bench configuration (TOML)")->required();
  simulate->add_option("--out", simulate_options.out, "dataset folder to write")->required();
  simulate->add_option("--seed", simulate_options.seed,
                       "another run of the same bench, every random stream drawn from this seed (held-out data)");
  simulate->add_option("--model", simulate_models,
                       "[SENSOR=]MODEL.toml: that sensor's output from this model file instead of the bench's truth parameters");

  inertia::commands::CharacterizeOptions characterize_options;
  auto* characterize = app.add_subcommand("characterize", "the paper's Fig. 1 procedure on a dataset: model.toml and a report");
  auto* characterize_dataset =
      characterize->add_option("--dataset", characterize_options.dataset, "dataset folder")->check(CLI::ExistingDirectory);
  auto* characterize_log = characterize->add_option("--log", characterize_options.event_log,
                                                    "inertia-daqd event log (LCM log file) instead of --dataset");
  characterize_dataset->excludes(characterize_log);
  characterize->add_option("--sensor", characterize_options.sensor, "with --log: the sensor under test (when the bench has several)")
      ->needs(characterize_log);
  characterize->add_option("--dataset-out", characterize_options.dataset_out, "with --log: also write the converted dataset folder")
      ->needs(characterize_log);
  characterize->add_option("--out", characterize_options.out, "output folder (model.toml, report.md, plots)")->required();
  characterize->add_option("--order", characterize_options.order, "model order r of the batch candidates")->capture_default_str();
  characterize->add_option("--misalignment-order", characterize_options.misalignment_order,
                           "model order r of the algorithm-2 candidates")->capture_default_str();
  characterize->add_option("--noise-lags", characterize_options.noise_lags, "MA lags of the batch fit (-1: = order)")->capture_default_str();
  characterize->add_option("--fixed-model", characterize_options.fixed_model, "block 10: fit these F_S terms instead of selecting")->delimiter(',');
  characterize->add_option("--misalignment-model", characterize_options.misalignment_model,
                           "blocks 5-6: fit these F_E-and-F_S terms instead of selecting")->delimiter(',');
  std::vector<std::string> weights;
  characterize->add_option("--weight", weights, "CASE=WEIGHT, per-case batch weight (section 3.4)")->delimiter(',');
  characterize->add_option("--alpha", characterize_options.alpha, "t-test significance level")->capture_default_str();
  characterize->add_option("--mounting-tolerance-deg", characterize_options.mounting_tolerance_deg,
                           "a mounting angle the plan cannot determine is held at nominal and taken within this (1 sd)")
      ->capture_default_str();
  characterize->add_option("--record", characterize_options.record_db,
                           "append this characterization to the lab's record: an SQLite file or a postgresql:// URL (default: "
                           "$INERTIA_RECORD; none: not recorded)");
  characterize->add_option("--serial", characterize_options.serial,
                           "the sensor's serial number (default: the bench file's, else its name); refused if the bench states another");
  characterize->add_option("--part", characterize_options.part,
                           "the sensor's type, its population in record compare (default: the bench file's); refused if the bench states another");
  characterize->add_option("--operator", characterize_options.operator_name, "with --record: who ran the test (default: the login name)");

  inertia::commands::ReproducePaperOptions paper_options;
  paper_options.bench = std::filesystem::path(INERTIA_SOURCE_DIR) / "config" / "sim-paper.toml";
  paper_options.seeds = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  auto* paper = app.add_subcommand("reproduce-paper", "the paper's section 3 over several seeds: tables 2, 3, 4 beside the paper's");
  paper->add_option("--json", paper_options.json, "write the figures as JSON");
  paper->add_option("--bench", paper_options.bench, "the paper's bench file")->capture_default_str()->check(CLI::ExistingFile);
  paper->add_option("--seeds", paper_options.seeds, "simulation seeds")->delimiter(',')->capture_default_str();
  paper->add_option("--order", paper_options.order, "model order r of case (4)")->capture_default_str();

  inertia::commands::DiagnoseCommandOptions diagnose_options;
  auto* diagnose = app.add_subcommand("diagnose", "where simulation and measurement disagree, and which effect is missing");
  diagnose->add_option("--model", diagnose_options.model, "model file (TOML)")->required()->check(CLI::ExistingFile);
  auto* diagnose_dataset =
      diagnose->add_option("--dataset", diagnose_options.dataset, "dataset folder")->check(CLI::ExistingDirectory);
  auto* diagnose_log =
      diagnose->add_option("--log", diagnose_options.event_log, "inertia-daqd event log (LCM log file) instead of --dataset");
  diagnose_dataset->excludes(diagnose_log);
  diagnose->add_option("--sensor", diagnose_options.sensor, "with --log: the sensor under test (when the bench has several)")
      ->needs(diagnose_log);
  diagnose->add_option("--json", diagnose_options.json, "write the findings as JSON")->required();
  diagnose->add_option("--report", diagnose_options.report, "report folder (report.md, plots, augmented model)");
  diagnose->add_option("--summary", diagnose_options.log, "also write the console summary to this file");
  diagnose->add_option("--alpha", diagnose_options.alpha, "family-wise significance level of each search step")->capture_default_str();

  inertia::commands::NoiseCommandOptions noise_options;
  auto* noise = app.add_subcommand("noise", "the sensor's noise at rest: Allan deviation, Q N B K R with intervals, PSD");
  auto* noise_dataset = noise->add_option("--dataset", noise_options.dataset, "dataset folder")->check(CLI::ExistingDirectory);
  auto* noise_log = noise->add_option("--log", noise_options.event_log, "inertia-daqd event log instead of --dataset");
  noise_dataset->excludes(noise_log);
  noise->add_option("--sensor", noise_options.sensor, "with --log: the sensor under test (when the bench has several)")
      ->needs(noise_log);
  noise->add_option("--case", noise_options.case_name, "only this case, all its rows (default: every static stretch)");
  noise->add_option("--tau-max", noise_options.tau_max_s, "fit averaging times up to this (s; default: as far as the data go)");
  noise->add_option("--out", noise_options.out, "output folder (noise.toml, report.md, plots)")->required();

  inertia::commands::CompensateOptions compensate_options;
  std::string other_axes = "reference";
  auto* compensate = app.add_subcommand("compensate", "raw output to physical input by the model read backwards, with uncertainty");
  compensate->add_option("--model", compensate_options.model, "model file (characterize's model.toml), or a unit's unit.toml (its outputs solved together)")->required()->check(CLI::ExistingFile);
  auto* compensate_dataset = compensate->add_option("--dataset", compensate_options.dataset, "dataset folder (for a unit: the folder of its members' datasets, one per member by name)")->check(CLI::ExistingDirectory);
  auto* compensate_log = compensate->add_option("--log", compensate_options.event_log, "inertia-daqd event log instead of --dataset");
  compensate_dataset->excludes(compensate_log);
  compensate->add_option("--sensor", compensate_options.sensor, "with --log: the sensor under test (default: the model's sensor_name)")
      ->needs(compensate_log);
  compensate->add_option("--out", compensate_options.out, "CSV of the compensated samples")->required();
  compensate->add_option("--other-axes", other_axes, "the other two axes of the sensed quantity: from the references, or zero")
      ->check(CLI::IsMember({"reference", "zero"}))
      ->capture_default_str();
  std::string case_frames = "model";
  compensate->add_option("--case-frames", case_frames,
                         "each case's M_E^S: as characterized (the model's [[case_frame]] of that name), or nominal")
      ->check(CLI::IsMember({"model", "nominal"}))
      ->capture_default_str();
  compensate->add_option("--range-margin", compensate_options.range_margin,
                         "flag a sample whose input lies beyond the characterized range by more than this fraction of it")
      ->capture_default_str();

  inertia::commands::ExportOptions export_options;
  std::string precision = "double";
  auto* export_verb = app.add_subcommand("export", "a model in its users' forms: C for firmware, JSON, Kalibr's imu.yaml");
  export_verb->add_option("--model", export_options.model, "model file (characterize's model.toml), or a unit's unit.toml (imucal, kalibr, json)")->required()->check(CLI::ExistingFile);
  export_verb->add_option("--format", export_options.format, "c, json or kalibr; imucal for a unit")
      ->required()
      ->check(CLI::IsMember({"c", "json", "kalibr", "imucal"}));
  export_verb->add_option("--out", export_options.out, "output folder")->required();
  export_verb->add_option("--prefix", export_options.prefix, "c: prefix of the generated names (default: inertia_<sensor>)");
  export_verb->add_option("--precision", precision, "c: the generated code's real type")
      ->check(CLI::IsMember({"double", "float"}))
      ->capture_default_str();
  export_verb->add_option("--vectors", export_options.vectors, "c: dataset folder whose first case gives test vectors")
      ->check(CLI::ExistingDirectory);
  export_verb->add_option("--vector-samples", export_options.vector_samples, "c: test vectors' samples")->capture_default_str();

  std::vector<std::filesystem::path> unit_models;
  std::filesystem::path unit_out;
  auto* unit = app.add_subcommand("unit", "a unit's triads from its members' models: axes, non-orthogonality, imucal's K, R, b, K_ga");
  unit->add_option("--model", unit_models, "the members' model files: three of one triad, or six (x, y, z in any order)")
      ->required()
      ->check(CLI::ExistingFile);
  unit->add_option("--out", unit_out, "output folder (unit.toml, the members' model files, imucal.json)")->required();

  std::filesystem::path sheet_model, sheet_out;
  auto* sheet = app.add_subcommand("sheet", "the model's parameters in IEEE 1293 / 952 names with expanded uncertainty (k = 2)");
  sheet->add_option("--model", sheet_model, "model file (characterize's model.toml), or a unit's unit.toml (its outputs solved together)")->required()->check(CLI::ExistingFile);
  sheet->add_option("--out", sheet_out, "output folder (sheet.md, sheet.html, sheet.json)")->required();

  std::string record_db;
  std::string record_serial, record_parameter;
  long long record_id = 0;
  auto* record = app.add_subcommand("record", "the lab's record of characterizations: list, show, history, compare");
  record->require_subcommand(1);
  auto* record_list = record->add_subcommand("list", "every characterization recorded (of one serial)");
  auto* record_show = record->add_subcommand("show", "one characterization: its data, model and sheet");
  auto* record_history = record->add_subcommand("history", "one parameter across a sensor's characterizations, changes flagged (En > 1)");
  auto* record_compare = record->add_subcommand("compare", "a sensor against the population of its kind and part: percentile per parameter");
  const CLI::Validator record_location(
      [](const std::string& db) { return inertia::record::is_postgresql_url(db) ? std::string() : CLI::ExistingFile(db); },
      "FILE|postgresql://...");
  for (CLI::App* verb : {record_list, record_show, record_history, record_compare})
    verb->add_option("--db", record_db, "the record: its SQLite file, or a postgresql:// URL")->required()->check(record_location);
  record_list->add_option("--serial", record_serial, "only this serial number");
  record_show->add_option("--id", record_id, "the characterization's id (record list)")->required();
  record_history->add_option("--serial", record_serial, "the sensor's serial number")->required();
  record_compare->add_option("--serial", record_serial, "the sensor's serial number (its latest characterization)")->required();
  record_history->add_option("--parameter", record_parameter, "the sheet's parameter name, e.g. \"bias\"")->required();
  std::filesystem::path record_plot;
  record_history->add_option("--plot", record_plot, "also draw the history to this SVG file");

  inertia::commands::PlanCheckOptions plan_options;
  auto* plan_check = app.add_subcommand("plan-check", "before a test: what the bench's plan will determine, and each parameter's predicted sd");
  plan_check->add_option("--bench", plan_options.bench, "bench file (backend sim, [sensor.truth]: the sensor's expected values and noise)")
      ->required()
      ->check(CLI::ExistingFile);
  plan_check->add_option("--sensor", plan_options.sensor, "the sensor under test (default: the bench's first)");
  plan_check->add_option("--fixed-model", plan_options.fixed_model, "predict for these F_S terms (default: the model characterize selects)")
      ->delimiter(',');
  plan_check->add_option("--seeds", plan_options.seeds, "check the predicted sd against the spread over this many simulated runs")
      ->capture_default_str();
  plan_check->add_option("--alpha", plan_options.alpha, "t-test significance level of the selection")->capture_default_str();

  inertia::commands::OnlineCommandOptions online_options;
  std::vector<std::string> online_models, online_compare;
  auto* online = app.add_subcommand("online", "live: fuse the daemon's stream, recursive ULS per sensor, publish INERTIA_ESTIMATE_*");
  online->add_option("--config", online_options.config, "the bench file inertia-daqd runs")->required();
  online->add_option("--model", online_models, "[SENSOR=]MODEL.toml: terms and M_C^S to track (default: the paper's complete static model)");
  auto* online_duration = online->add_option("--duration", online_options.duration_s, "stop after S seconds (default: until SIGINT/SIGTERM)");
  online->add_option("--publish-hz", online_options.publish_hz, "estimate publishing rate")->capture_default_str();
  online->add_option("--forgetting", online_options.forgetting, "forgetting factor lambda in (0, 1] per sample")->capture_default_str();
  auto* online_url = online->add_option("--lcm-url", online_options.lcm_url, "LCM provider (default: $LCM_DEFAULT_URL or LCM's default)");
  online->add_option("--noise-window", online_options.noise_window_s, "seconds of rows that fit the noise model (0: white noise)")->capture_default_str();
  online->add_option("--history", online_options.history, "write every published estimate to this CSV file");
  // A replay reads a file to its end and publishes nothing: a duration or a provider would be ignored.
  online->add_option("--replay", online_options.replay, "run on a recorded event log instead of the live stream")
      ->check(CLI::ExistingFile)
      ->excludes(online_duration)
      ->excludes(online_url);
  online->add_option("--compare", online_compare,
                     "[SENSOR=]MODEL.toml: at the end, print that sensor's live estimate beside this model file (read then)");

  // The offline verbs' threads (common/parallel.hpp); online keeps one, beside the daemon.
  int jobs = 0;
  for (CLI::App* verb : {characterize, diagnose, noise, plan_check, paper})
    verb->add_option("--jobs", jobs, "threads for the per-column filters and transforms, and for the simulated runs "
                                     "of plan-check and reproduce-paper side by side (0: the machine's cores); the "
                                     "results do not depend on it")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? inertia::kExitOk : inertia::kExitBadInput;
  }

  if (characterize->parsed() || diagnose->parsed() || noise->parsed() || plan_check->parsed() || paper->parsed())
    inertia::parallel::set_jobs(jobs);
  if (simulate->parsed()) {
    simulate_options.models = parse_models(simulate_models);
    return inertia::commands::run_simulate(simulate_options, std::cout);
  }
  if (diagnose->parsed()) return inertia::commands::run_diagnose(diagnose_options, std::cout);
  if (record_list->parsed()) return inertia::commands::run_record_list(record_db, record_serial, std::cout);
  if (record_show->parsed()) return inertia::commands::run_record_show(record_db, record_id, std::cout);
  if (record_history->parsed()) return inertia::commands::run_record_history(record_db, record_serial, record_parameter, std::cout, record_plot);
  if (record_compare->parsed()) return inertia::commands::run_record_compare(record_db, record_serial, std::cout);
  if (sheet->parsed()) return inertia::commands::run_sheet(sheet_model, sheet_out, std::cout);
  if (unit->parsed()) return inertia::commands::run_unit(unit_models, unit_out, std::cout);
  if (export_verb->parsed()) {
    export_options.single_precision = precision == "float";
    return inertia::commands::run_export(export_options, std::cout);
  }
  if (compensate->parsed()) {
    compensate_options.other_axes_zero = other_axes == "zero";
    compensate_options.case_frames_from_model = case_frames == "model";
    return inertia::commands::run_compensate(compensate_options, std::cout);
  }
  if (noise->parsed()) return inertia::commands::run_noise(noise_options, std::cout);
  if (online->parsed()) {
    online_options.models = parse_models(online_models);
    online_options.compare = parse_models(online_compare);
    return inertia::commands::run_online(online_options, std::cout);
  }
  if (paper->parsed()) return inertia::commands::run_reproduce_paper(paper_options, std::cout);
  if (plan_check->parsed()) return inertia::commands::run_plan_check(plan_options, std::cout);
  if (characterize->parsed()) {
    characterize_options.weights = parse_weights(weights);
    if (characterize_options.record_db.empty()) {
      if (const char* db = std::getenv("INERTIA_RECORD"); db != nullptr && *db != '\0') characterize_options.record_db = db;
    }
    return inertia::commands::run_characterize(characterize_options, std::cout);
  }
  return inertia::kExitBadInput;
}

/// glibc's malloc as the analysis wants it, a process-wide policy set here and not in the library.
/// The analysis allocates and frees regressor matrices of tens of MB (the paper plan) to GB (an
/// hour at 10 kHz) hundreds of times, each written right after allocation:
///  - freed memory stays in the heap, whatever its size, so the next matrix reuses pages already
///    faulted in (by default glibc maps each large block afresh and unmaps it on free, or trims
///    the heap after it);
///  - the heap and any mapped block are advised MADV_HUGEPAGE (glibc.malloc.hugetlb=1): a fault
///    per 2 MB instead of per 4 KiB;
///  - one arena for every thread: the --jobs threads' buffers return to the heap the next matrix
///    reuses instead of staying in an arena of their own.
/// Their effect grows with the record (docs/validation.md, 'Evidence behind choices in the
/// code'). glibc reads the tunables that say so from the environment at process start only, so
/// the program runs itself again, once, with them put before any others in GLIBC_TUNABLES: the
/// same PID, arguments and open files. A marker variable, removed in the second run, says the
/// tunables are in force (glibc may rewrite GLIBC_TUNABLES as it reads it). A caller who sets any
/// glibc.malloc tunable gets exactly those. Where the program is not run again (the kernel has no
/// huge pages; valgrind, whose tools follow a new image only when asked; an exec that fails),
/// mallopt keeps freed blocks up to 1 GB in the heap and the pages stay 4 KiB.
///
/// The run again also sets OpenMP's wait policy to passive where the caller set none: libgomp's
/// default spins a thread that finished its share of a parallel region for a while before it
/// sleeps, and the analysis runs many short regions beside its own thread pool
/// (common/parallel.hpp), whose threads then wait for a core the spinning one holds. libgomp
/// also reads it at process start only (docs/validation.md, 'Evidence behind choices in the code').
void configure_malloc(char** argv) {
  constexpr const char* kConfigured = "INERTIA_ANALYZE_MALLOC_TUNED";
  constexpr std::string_view kMallocTunables =
      "glibc.malloc.hugetlb=1:glibc.malloc.mmap_threshold=1099511627776:glibc.malloc.trim_threshold=1099511627776:"
      "glibc.malloc.arena_max=1";
  if (std::getenv(kConfigured) != nullptr) {
    ::unsetenv(kConfigured);
    return;
  }
  const char* given = std::getenv("GLIBC_TUNABLES");
  const std::string tunables = given != nullptr ? given : "";
  if (tunables.find("glibc.malloc.") != std::string::npos) return;
  const auto huge_pages_available = [] {
    std::ifstream mode("/sys/kernel/mm/transparent_hugepage/enabled");
    std::string modes;
    return std::getline(mode, modes) && modes.find("[never]") == std::string::npos;
  };
  const char* preload = std::getenv("LD_PRELOAD");
  const bool under_valgrind = preload != nullptr && std::strstr(preload, "vgpreload") != nullptr;
  if (!under_valgrind && huge_pages_available()) {
    const std::string with_ours = std::string(kMallocTunables) + (tunables.empty() ? "" : ":" + tunables);
    const bool wait_policy_given = std::getenv("OMP_WAIT_POLICY") != nullptr;
    if (::setenv("GLIBC_TUNABLES", with_ours.c_str(), 1) == 0 && ::setenv(kConfigured, "1", 1) == 0 &&
        (wait_policy_given || ::setenv("OMP_WAIT_POLICY", "passive", 1) == 0))
      ::execv("/proc/self/exe", argv);
    ::unsetenv(kConfigured);
    if (!wait_policy_given) ::unsetenv("OMP_WAIT_POLICY");
    if (given != nullptr) {
      ::setenv("GLIBC_TUNABLES", tunables.c_str(), 1);
    } else {
      ::unsetenv("GLIBC_TUNABLES");
    }
  }
  mallopt(M_MMAP_THRESHOLD, 1024 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024);
  mallopt(M_ARENA_MAX, 1);
}

}  // namespace

int main(int argc, char** argv) {
  configure_malloc(argv);
  try {
    return run(argc, argv);
  } catch (const inertia::InputError& e) {
    std::cerr << "inertia-analyze: " << e.what() << '\n';
    return inertia::kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << "inertia-analyze: error: " << e.what() << '\n';
    return inertia::kExitFailure;
  }
}
