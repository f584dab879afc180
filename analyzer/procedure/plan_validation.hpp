#pragma once
// What a plan can determine, said before and after the fit: input checks with advice (bad input
// is an InputError that says what the plan needs), the terms offered to the selection, and why a
// candidate the plan does not determine is left out.
#include <Eigen/Dense>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "analyzer/ident/candidates.hpp"
#include "analyzer/ident/term.hpp"
#include "analyzer/procedure/excitation.hpp"
#include "analyzer/procedure/pipeline_options.hpp"
#include "analyzer/procedure/pipeline_result.hpp"
#include "analyzer/procedure/stacked_regression.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::procedure {

/// InputError for a dataset the procedure cannot run on: no cases, a weight for a case it does
/// not have, a gyroscope case without rates, or a plan whose sensitive input does not vary (the
/// scale factor cannot be told from the bias).
void check_plan(const dataset::Dataset& data, const PipelineOptions& options, std::string_view dataset_label);

/// InputError naming a weight whose case the dataset does not have.
void check_case_weights(const dataset::Dataset& data, const PipelineOptions& options);

/// The terms `choice` offers in `frame`: the candidates (with the temperature terms when the
/// fixture temperature varies enough, PipelineOptions::temperature_when_measured), or its fixed
/// model (`what` names it in the error when it is empty).
std::vector<ident::Term> offered_terms(const ModelChoice& choice, ident::ModelFrame frame, const dataset::Dataset& data,
                                       const PipelineOptions& options, const char* what);

/// The note for the user when the temperature terms are not offered because the fixture
/// temperature does not vary enough; none otherwise.
std::optional<std::string> temperature_note(const dataset::Dataset& data, const PipelineOptions& options);

/// Whether the plan itself excites a product of inertial inputs. A term's column is evaluated with
/// each case's inputs in its nominal frame (the plan's case frame, M_E^C, without the sensor's
/// misalignment) and again with each inertial factor carrying its whole input vector's magnitude.
/// Where the first holds less than kMinExcitationShare of the second's energy, only the sensor's
/// own misalignment and the poses' scatter move the term: on a six-pose tumble a_p*a_o reaches a
/// few mrad of g^2 while its inputs' range allows g^2/2, so a coefficient fitted there answers
/// pose-to-pose noise and is extrapolated a hundredfold wherever the model is applied. The batch
/// (remove_unexcited_terms) and the live estimator (online/case_accumulator.hpp) both tally it
/// with add_excitation.
struct TermExcitation {
  double nominal = 0.0;   // the column's energy with the inputs in the nominal frame
  double full = 0.0;      // ... with each inertial factor at its input vector's magnitude
  [[nodiscard]] bool excited() const { return !(full > 0.0) || nominal >= kMinExcitationShare * full; }
  void scale(double f) { nominal *= f, full *= f; }
};

/// Whether the rule judges `term`: two or more inertial factors (counting powers), none of the
/// output or its noise. A term of one inertial factor is a sensitivity, which the axes' rule of
/// excitation.hpp judges; the bias and the temperature alone are not inertial.
[[nodiscard]] bool judged_by_excitation(const ident::Term& term);

/// Adds to `tallies[i]`, for each of `terms[i]` the rule judges, the rows from `first_row` on of
/// `c`, its references turned into the nominal frame by `m_nominal` (the case's m_ec; the identity
/// for references already in that frame) and read as `reading` says. Rows before a term's largest
/// lag are skipped; a case without a term's rates or temperature adds nothing to it. The case's
/// signals are built once.
void add_excitation(std::span<const ident::Term> terms, const dataset::CaseData& c, const Eigen::Matrix3d& m_nominal, double t_ref,
                    Eigen::Index first_row, std::span<TermExcitation> tallies, const ident::CaseReading& reading = {});

/// Why a term with `tally` is not determined, for the user.
std::string unexcited_reason(const ident::Term& term, const TermExcitation& tally);

/// Takes out of `candidates` the terms judged_by_excitation that `cases` do not excite, and says
/// why for each.
std::vector<UndeterminedTerm> remove_unexcited_terms(std::vector<ident::Term>& candidates, std::span<const dataset::CaseData> cases,
                                                     double t_ref);
/// The same over cases as a stack reads them: each input's M_E^S taken as its nominal frame.
std::vector<UndeterminedTerm> remove_unexcited_terms(std::vector<ident::Term>& candidates, std::span<const StackInput> inputs,
                                                     double t_ref);

/// The columns of `s` that are not in `ranking` (identifiable_ranking), each with why: a zero
/// column needs excitation of its variables; otherwise it is (nearly) a combination of ranked
/// columns, named by their shares.
std::vector<UndeterminedTerm> undetermined_columns(const StackedRegression& s, const std::vector<Eigen::Index>& ranking);

}  // namespace inertia::procedure
