#pragma once
// The calibration sheet: a model file's content in the names of the standards a lab certifies
// against (IEEE Std 1293 for accelerometers, IEEE Std 952 for gyroscopes), each value with its
// expanded uncertainty (k = 2, as the GUM writes it) and how it derives from the model.
//
// Every deterministic parameter is a function of the model's coefficients, taken on the model's
// static response (compensate/static_response.hpp): bias, scale factor and its nonlinearity over
// the characterized range, cross-axis, cross-coupling, g-sensitivity, temperature coefficients,
// so lags and rational terms count as they act on a settled input. Its uncertainty is the delta
// method's, u^2 = J C J' with the model's covariance C (its [std] alone without [covariance]) and
// J by central differences. The misalignment comes from the model's [misalignment] angles, the
// noise parameters from its [noise] terms (N, B, K, Q) over the static sensitivity.
// A parameter whose terms the plan did not determine says why ([undetermined]); one the selection
// left out says so. Neither is ever written as 0.
//
// The sheet's plots come from the same model: the scale-factor nonlinearity over the characterized
// range (the static response less its least-squares line, with its delta-method band), the Allan
// deviation the [noise] terms imply (IEEE Std 952 Annex C), and the bias over the tested
// temperatures. The HTML page draws them with gnuplot as inline SVG.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "analyzer/model/model_file.hpp"

namespace inertia::report {

struct SheetEntry {
  std::string name;           // the standard's name: "bias", "scale factor", ...
  std::string symbol;         // K0, K1, K2, ...
  std::string unit;           // "ug", "mA/g", "ppm/degC", ...
  enum class Status { Determined, Undetermined, NotSelected } status = Status::Determined;
  double value = 0.0;         // Determined only
  double expanded_uncertainty = 0.0;   // k = 2
  std::string derivation;     // how it follows from the model
  std::vector<std::string> terms;      // the model terms it traces to
  std::string reason;         // Undetermined / NotSelected: why, and what would determine it
};

/// One curve of a plot: its values at the plot's x.
struct SheetSeries {
  std::string title;
  std::vector<double> y;
  std::vector<double> expanded_uncertainty;   // k = 2 at each x, drawn as a band; empty: no band
  bool dashed = false;                        // a component of the solid total beside it
};

/// A plot of the sheet, computed from the model.
struct SheetPlot {
  std::string name;   // "scale-factor nonlinearity", ...
  std::string x_label, y_label;
  bool log_log = false;
  std::vector<double> x;
  std::vector<SheetSeries> series;
  /// A second y axis at y2_per_y times y (0: none), e.g. ppm of full scale beside the output unit.
  std::string y2_label;
  double y2_per_y = 0.0;
  std::string trace;         // what the plot is computed from: the page's caption
  std::string not_drawable;  // non-empty: why the model cannot give the plot (x and series are empty)
};

struct ParameterSheet {
  std::string sensor_kind, sensor_name, output_unit;
  std::vector<SheetEntry> entries;
  std::vector<std::string> conditions;   // "temperature 15.0 to 35.0 degC", ...
  std::vector<SheetPlot> plots;          // nonlinearity, Allan deviation, bias over temperature
};

/// The sheet of `model`. Throws InputError for a model without a term in the sensed input (no
/// scale factor, so nothing converts to input units).
ParameterSheet parameter_sheet(const model::ModelFile& model);

std::string sheet_markdown(const ParameterSheet& sheet);
/// A self-contained HTML page (no external resource, no script): the table, the conditions and the
/// plots, each an inline SVG gnuplot draws in a scratch directory under the system's temporary one,
/// or a sentence saying why it is not drawn (gnuplot absent or failing, the model lacking what it needs).
std::string sheet_html(const ParameterSheet& sheet);
/// The sheet as JSON against tests/schema/sheet.schema.json.
nlohmann::json sheet_json(const ParameterSheet& sheet);

}  // namespace inertia::report
