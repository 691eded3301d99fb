#include "src/point_checkpoint.hpp"

#include <cmath>
#include <utility>

namespace pdsim {

namespace {

// Each number a point keeps, in its place in the checkpoint: how it is read from a point, how
// it is put back, and what it is in a checkpoint written before it was kept (nullptr: it always
// was). A new per-point quantity is one line, appended.
struct PointField {
  double (*get)(const FrequencyPoint&);
  void (*set)(FrequencyPoint&, double);
  void (*absent)(FrequencyPoint&);
};

#define PDSIM_POINT_FIELD(member, to_double, from_double, absent)              \
  PointField {                                                                 \
    [](const FrequencyPoint& p) { return to_double(p.member); },               \
        [](FrequencyPoint& p, double v) { p.member = from_double(v); }, absent \
  }

double same(double v) {
  return v;
}
double from_int(int v) {
  return double(v);
}
int to_int(double v) {
  return static_cast<int>(v);
}
double from_bool(bool v) {
  return double(v);
}
bool to_bool(double v) {
  return v != 0;
}

// A dissipation mechanism added after the checkpoint's layout was fixed: NaN in older ones.
template <int M>
PointField later_mechanism() {
  return {[](const FrequencyPoint& p) { return p.mean.dissipated[M]; },
          [](FrequencyPoint& p, double v) { p.mean.dissipated[M] = v; },
          [](FrequencyPoint& p) { p.mean.dissipated[M] = std::nan(""); }};
}
template <std::size_t... M>
void append_later_mechanisms(std::vector<PointField>& fields, std::index_sequence<M...>) {
  (fields.push_back(later_mechanism<kRolling + 1 + int(M)>()), ...);
}

const std::vector<PointField> kPointFields = [] {
  std::vector<PointField> fields = {
      PDSIM_POINT_FIELD(frequency, same, same, nullptr),
      {[](const FrequencyPoint& p) { return p.judged.mean.real(); },
       [](FrequencyPoint& p, double v) { p.judged.mean.real(v); }, nullptr},
      {[](const FrequencyPoint& p) { return p.judged.mean.imag(); },
       [](FrequencyPoint& p, double v) { p.judged.mean.imag(v); }, nullptr},
      PDSIM_POINT_FIELD(judged.amplitude_ci, same, same, nullptr),
      PDSIM_POINT_FIELD(judged.phase_ci, same, same, nullptr),
      PDSIM_POINT_FIELD(judged.discarded, from_int, to_int, nullptr),
      PDSIM_POINT_FIELD(judged.batch_length, from_int, to_int, nullptr),
      PDSIM_POINT_FIELD(judged.batches, from_int, to_int, nullptr),
      PDSIM_POINT_FIELD(judged.periods, from_int, to_int, nullptr),
      PDSIM_POINT_FIELD(judged.lag1, same, same, nullptr),
      PDSIM_POINT_FIELD(judged.trend, from_bool, to_bool, nullptr),
      PDSIM_POINT_FIELD(judged.converged, from_bool, to_bool, nullptr),
      PDSIM_POINT_FIELD(mean.mean_square, same, same, nullptr),
      PDSIM_POINT_FIELD(mean.peak, same, same, nullptr),
      PDSIM_POINT_FIELD(energy_in.mean, same, same, nullptr),
      PDSIM_POINT_FIELD(energy_in.half_width, same, same, nullptr),
      PDSIM_POINT_FIELD(mean.dissipated[kNormal], same, same, nullptr),
      PDSIM_POINT_FIELD(mean.dissipated[kTangential], same, same, nullptr),
      // Kept since rolling resistance was tallied; before, it was not measured.
      PDSIM_POINT_FIELD(mean.dissipated[kRolling], same, same,
                        [](FrequencyPoint& p) { p.mean.dissipated[kRolling] = std::nan(""); }),
      // Kept since a fill held still counts as settled; before, only converged fills did.
      PDSIM_POINT_FIELD(judged.stationary, from_bool, to_bool,
                        [](FrequencyPoint& p) { p.judged.stationary = p.judged.converged; }),
  };
  append_later_mechanisms(fields, std::make_index_sequence<kMechanisms - kRolling - 1>());
  // Kept since fills stop at looks (by_spread) and a drift at the cap can count (drift).
  fields.push_back(PDSIM_POINT_FIELD(judged.by_spread, from_bool, to_bool,
                                     [](FrequencyPoint& p) { p.judged.by_spread = false; }));
  fields.push_back(PDSIM_POINT_FIELD(judged.drift, same, same,
                                     [](FrequencyPoint& p) { p.judged.drift = std::nan(""); }));
  return fields;
}();
#undef PDSIM_POINT_FIELD

const std::size_t kFields = kPointFields.size();
// The fields every checkpoint holds: those that were kept from the start.
const std::size_t kAlwaysKept = [] {
  std::size_t n = 0;
  while (n < kFields && kPointFields[n].absent == nullptr) ++n;
  return n;
}();

}  // namespace

std::vector<double> pack(const FrequencyPoint& p) {
  std::vector<double> out;
  out.reserve(kFields);
  for (const PointField& f : kPointFields) out.push_back(f.get(p));
  return out;
}

FrequencyPoint unpack(const std::vector<double>& v) {
  if (v.size() < kAlwaysKept || v.size() > kFields)
    throw SimulationError("checkpoint point of an unknown layout");
  FrequencyPoint p;
  for (std::size_t k = 0; k < kFields; ++k)
    if (k < v.size())
      kPointFields[k].set(p, v[k]);
    else
      kPointFields[k].absent(p);
  p.judged.reason = p.judged.converged ? "" : "not converged";
  return p;
}

std::vector<double> pack_periods(const FrequencyPoint& p) {
  std::vector<double> out;
  for (const PeriodSummary& s : p.periods)
    out.insert(out.end(), {s.displacement.real(), s.displacement.imag(), s.force.real(),
                           s.force.imag(), s.energy_in});
  return out;
}

void unpack_periods(const std::vector<double>& v, FrequencyPoint& p) {
  for (std::size_t k = 0; k + 5 <= v.size(); k += 5) {
    PeriodSummary s;
    s.displacement = {v[k], v[k + 1]};
    s.force = {v[k + 2], v[k + 3]};
    s.energy_in = v[k + 4];
    p.periods.push_back(s);
  }
}

}  // namespace pdsim
