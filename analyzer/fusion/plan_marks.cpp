// The test plan's markers as the stream assembler has received them (plan_marks.hpp).
#include "analyzer/fusion/plan_marks.hpp"

#include <algorithm>

namespace inertia::fusion {

void PlanMarks::add(const plan_event_t& ev, std::size_t index, double period_ns, const std::string& where,
                    std::vector<std::string>& notes) {
  CaseMarks* open = nullptr;
  for (CaseMarks& c : cases)
    if (!c.ended) open = &c;
  switch (ev.mark) {
    case plan_event_t::MARK_CASE_START:
      saw_case_marker = true;
      if (open != nullptr) {
        // A bench runs one case at a time: the new start ends the open one (its end marker was
        // lost, or the case was restarted).
        notes.push_back(where + ": case " + ev.case_name + " started while case " + open->name +
                        " had not ended: that case ends here");
        open->ended = true;
        open->last_ns = static_cast<double>(ev.start_mono_ns) - period_ns;
      }
      cases.push_back({index, ev.case_name, static_cast<double>(ev.start_mono_ns), 0.0, false, false, {}});
      break;
    case plan_event_t::MARK_CASE_END:
    case plan_event_t::MARK_ABORT:
      if (open == nullptr || open->case_index != index) {
        notes.push_back(where + ": end of case " + ev.case_name + " without its start: ignored");
        break;
      }
      open->ended = true;
      open->aborted = ev.mark == plan_event_t::MARK_ABORT;
      open->last_ns = static_cast<double>(ev.mark == plan_event_t::MARK_ABORT ? ev.mono_ns : ev.end_mono_ns);
      if (open->aborted) notes.push_back(where + ": case " + ev.case_name + " aborted; its samples up to the abort are used");
      break;
    case plan_event_t::MARK_PHASE_START:
      if (open == nullptr || open->case_index != index) {
        notes.push_back(where + ": phase marker of case " + ev.case_name + " outside the case: ignored");
        break;
      }
      open->phases.push_back({static_cast<double>(ev.start_mono_ns), static_cast<double>(ev.end_mono_ns),
                              ev.phase_index, ev.phase.empty() ? std::string("phase") : ev.phase});
      std::stable_sort(open->phases.begin(), open->phases.end(),
                       [](const PhaseMark& a, const PhaseMark& c) { return a.start_ns < c.start_ns; });
      break;
    default: break;  // MARK_PHASE_END: the next start (or the case end) closes a phase
  }
  const double t = static_cast<double>(std::max({ev.mono_ns, ev.start_mono_ns, ev.mark == plan_event_t::MARK_CASE_END ? ev.end_mono_ns : 0}));
  newest_ns = std::max(newest_ns, t);
}

CaseMarks* PlanMarks::case_of(double t, double half, bool given_up, bool& ready) {
  ready = true;
  for (CaseMarks& c : cases) {
    if (t < c.start_ns - half) continue;
    if (c.ended && t > c.last_ns + half) continue;
    return &c;
  }
  // No case holds it: a start marker could still come for it.
  if (newest_ns < t && !given_up) ready = false;
  return nullptr;
}

bool PlanMarks::phase_settled(const CaseMarks& c, double t, double half, bool given_up) const {
  if (newest_ns > t + half || c.ended) return true;
  const PhaseMark* current = nullptr;
  for (const PhaseMark& p : c.phases)
    if (p.start_ns <= t + half) current = &p;
  if (current != nullptr && current->end_ns > t + half) return true;
  return given_up;
}

}  // namespace inertia::fusion
