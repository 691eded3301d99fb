#include "src/run_record.hpp"

#include <algorithm>
#include <string>

#include "src/point_checkpoint.hpp"

namespace pdsim {

namespace {
std::string bed_key(std::size_t r) {
  return "bed.r" + std::to_string(r) + ".";
}
std::string point_key(std::size_t r, std::size_t i) {
  return "point.r" + std::to_string(r) + ".f" + std::to_string(i);
}
std::string state_key(std::size_t r) {
  return "task.r" + std::to_string(r) + ".";
}
BedReport bed_report(const StateArrays& in, std::size_t r) {
  const std::vector<double>& v = state_values<double>(in, "bed.reports");
  if (v.size() < 4 * (r + 1))
    throw SimulationError("the checkpoint's bed.reports should hold 4 values a realisation");
  return {v[4 * r] != 0, v[4 * r + 1] != 0, v[4 * r + 2], v[4 * r + 3]};
}
}  // namespace

RunRecord::RunRecord(std::size_t fills, std::size_t count)
    : beds(fills),
      reports(fills),
      points(fills, std::vector<std::optional<FrequencyPoint>>(count)),
      looks(fills, std::vector<std::vector<std::complex<double>>>(count)),
      done(count, 0) {}

std::size_t RunRecord::fills_begun() const {
  std::size_t fills = 0;
  for (std::size_t r = 0; r < beds.size(); ++r)
    if (!beds[r].empty()) fills = r + 1;
  return fills;
}

long RunRecord::reached(std::size_t r) const {
  for (std::size_t i = points[r].size(); i-- > 0;)
    if (points[r][i]) return static_cast<long>(i);
  return -1;
}

void put_beds(const RunRecord& record, std::size_t count, StateArrays& out) {
  std::vector<double> reports;
  for (std::size_t r = 0; r < count; ++r) {
    put_state(out, bed_key(r), record.beds[r]);
    const BedReport& b = record.reports[r];
    reports.insert(reports.end(), {double(b.ran), double(b.settled), b.time_s, b.speed});
  }
  out["bed.reports"] = reports;
}

void get_beds(const StateArrays& in, std::size_t count, RunRecord& record) {
  for (std::size_t r = 0; r < std::min(count, record.beds.size()); ++r)
    if (record.beds[r].empty()) {
      record.beds[r] = get_state(in, bed_key(r));
      if (!record.beds[r].empty()) record.reports[r] = bed_report(in, r);
    }
}

void put_checkpoint(const RunRecord& record, double wall_s, StateArrays& c) {
  const std::size_t fills = record.fills_begun();
  put_beds(record, fills, c);
  c["run.fills"] = std::vector<std::int32_t>{static_cast<std::int32_t>(fills)};
  c["run.done"] = std::vector<std::int32_t>(record.done.begin(), record.done.end());
  if (record.bed_from_file) c["bed.from_file"] = std::vector<std::int32_t>{1};
  for (std::size_t k = 0; k < fills; ++k)
    for (std::size_t f = 0; f < record.done.size(); ++f)
      if (const auto& p = record.points[k][f]) {
        c[point_key(k, f)] = pack(*p);
        c[point_key(k, f) + ".periods"] = pack_periods(*p);
        if (!record.looks[k][f].empty()) {
          std::vector<double> looks;
          for (const auto& h : record.looks[k][f]) looks.insert(looks.end(), {h.real(), h.imag()});
          c[point_key(k, f) + ".looks"] = std::move(looks);
        }
      }
  for (const auto& [k, state] : record.states) put_state(c, state_key(k), state);
  c["run.totals"] = std::vector<double>{double(record.particle_steps), record.simulated_s, wall_s};
}

void get_checkpoint(const StateArrays& c, RunRecord& record) {
  record.bed_from_file = c.count("bed.from_file") > 0;
  const auto& done = state_values<std::int32_t>(c, "run.done");
  if (done.size() != record.done.size())
    throw SimulationError("the checkpoint's run.done should hold one flag a frequency");
  for (std::size_t s = 0; s < done.size(); ++s) record.done[s] = done[s] != 0;
  const auto filled = static_cast<std::size_t>(state_value<std::int32_t>(c, "run.fills"));
  get_beds(c, filled, record);
  for (std::size_t r = 0; r < filled && r < record.beds.size(); ++r) {
    for (std::size_t i = 0; i < record.done.size(); ++i)
      if (const auto it = c.find(point_key(r, i)); it != c.end()) {
        auto& point = record.points[r][i];
        point = unpack(state_values<double>(c, point_key(r, i)));
        unpack_periods(state_values<double>(c, point_key(r, i) + ".periods"), *point);
        if (c.count(point_key(r, i) + ".looks") > 0) {
          const auto& v = state_values<double>(c, point_key(r, i) + ".looks");
          for (std::size_t j = 0; j + 1 < v.size(); j += 2)
            record.looks[r][i].emplace_back(v[j], v[j + 1]);
        }
      }
    if (StateArrays state = get_state(c, state_key(r)); !state.empty())
      record.states[r] = std::move(state);
  }
  const auto& totals = state_values<double>(c, "run.totals");
  record.particle_steps = static_cast<long long>(totals.at(0));
  record.simulated_s = totals.at(1);
  record.wall_before_s = totals.at(2);
}

}  // namespace pdsim
