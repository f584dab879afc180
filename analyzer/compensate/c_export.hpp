#pragma once
// The compensation of compensate/inverse_model.hpp as dependency-free C99 for a sensor's
// firmware: one sample at a time, no allocation, its state in a struct the caller owns, and a
// bounded number of Newton steps (at most kStarts x max_iterations per sample). The generated
// code follows InverseModel step for step (the same starts, tolerance, settled start, hold across
// a sample without a root, squares' high pass), so the two agree to rounding. One generator
// (generate_joint_c, joint_c_export.cpp) writes both: one output is the joint solve of one
// equation and one unknown, behind the scalar API below.
//
// Generated API, for a prefix P (upper case PU):
//   typedef double|float P_real;
//   enum { PU_INPUTS = n, PU_TERMS = p, PU_HISTORY = L };
//   extern const char* const P_input_names[];            (the known inputs, in argument order)
//   typedef struct { ... } P_state;                      (zero it with P_init)
//   typedef struct { P_real value, u_coefficients, u_noise; int flag; } P_result;
//     flag: 0 ok, 1 outside the characterized range, 2 no root (value NaN), 3 filling the
//     history (the first L samples; value NaN)
//   void P_init(P_state* s);
//   P_result P_compensate(P_state* s, const P_real* inputs, P_real y);
//
// The test vectors (write_test_vectors) hold per sample y, the inputs in that order, and what
// InverseModel gives: a CI test compiles the code with -std=c99 -Wall -Werror and checks it.
#include <iosfwd>
#include <optional>
#include <utility>
#include <string>
#include <vector>

#include "analyzer/compensate/inverse_model.hpp"
#include "analyzer/compensate/joint_inverse.hpp"
#include "analyzer/ident/regressors.hpp"
#include "analyzer/model/model_file.hpp"

namespace inertia::compensate {

enum class CPrecision { Float, Double };

struct CSource {
  std::string header, source;
  std::vector<ident::Variable> inputs;   // the known inputs, in the order P_compensate takes them
};

/// Throws InputError for a prefix that is not a C identifier, or a model InverseModel refuses.
CSource generate_c(const model::ModelFile& model, const std::string& prefix, CPrecision precision,
                   const CompensationOptions& options = {});

/// CSV "y,<inputs>,value,u_coefficients,u_noise,flag" of `signals` compensated by InverseModel,
/// one row per sample (the first L rows flag 3, value nan), inputs in `inputs`' order.
void write_test_vectors(std::ostream& out, const model::ModelFile& model, const std::vector<ident::Variable>& inputs,
                        const ident::SignalSet& signals, double sample_period_s, const CompensationOptions& options = {});

/// Several outputs' joint compensation (joint_inverse.hpp; a unit's, unit/unit_inverse.hpp) as C99,
/// with the same guarantees. Generated API, for a prefix P (upper case PU), D unknowns:
///   enum { PU_UNKNOWNS = D, PU_OUTPUTS = D, PU_INPUTS = n, PU_HISTORY = L };
///   extern const char* const P_input_names[];    ("<output>.<input>": each output's known inputs)
///   extern const char* const P_unknown_names[];  (e.g. a_x, a_y, a_z, w_x, w_y, w_z)
///   typedef struct { P_real value[D], u_coefficients[D], u_noise[D]; int flag; } P_result;
///   void P_init(P_state* s);
///   P_result P_compensate(P_state* s, const P_real* inputs, const P_real* y);   y: the D outputs in order
struct JointCSource {
  std::string header, source;
  std::vector<std::pair<std::size_t, ident::Variable>> inputs;   // (output, known input), in P_compensate's order
};

/// One output's published API (above) over the joint solve of one equation: what generate_c asks
/// for. `description` names the sensor in the header's comment, `unit` its sensed input's unit,
/// `inputs_note` completes the inputs' comment (how T is taken).
struct COneOutput {
  std::string description, unit, inputs_note;
};

/// `output_names` names each equation's output (the member's sensor), `unknown_names` each
/// unknown. With `one_output`, the one-equation, one-unknown solve behind one output's API.
/// Throws InputError for a prefix that is not a C identifier, or a square high pass without
/// `sample_period_s`.
JointCSource generate_joint_c(const JointInverse& joint, const std::vector<std::string>& output_names,
                              const std::vector<std::string>& unknown_names, const std::string& prefix, CPrecision precision,
                              std::optional<double> sample_period_s, const CompensationOptions& options = {},
                              const COneOutput* one_output = nullptr);

/// CSV "y_<output>...,<inputs>...,<unknown>...,u_coefficients_<unknown>...,u_noise_<unknown>...,flag" of
/// `records` compensated by `joint`, one row per sample (the first L rows flag 3, values nan).
void write_joint_test_vectors(std::ostream& out, const JointInverse& joint, const std::vector<std::string>& output_names,
                              const std::vector<std::string>& unknown_names,
                              const std::vector<std::pair<std::size_t, ident::Variable>>& inputs,
                              const std::vector<const ident::SignalSet*>& records, double sample_period_s,
                              const CompensationOptions& options = {});

}  // namespace inertia::compensate
