// Records the dataflow of the hardware units from the kernel source: each unit's model (operands.hpp, which calls the
// kernel's function) runs on a scalar type whose operations append nodes to a graph instead of computing, and the
// graphs are written as JSON for tools/hardware/units.py, which schedules them and writes the Verilog.
//
//   record_graphs > graphs.json        (units.py compiles and runs this itself where no --graphs file is given)
//
// A kernel function branches on comparisons (an early return on a miss, the nearer root or the farther). A recorded
// comparison is a bit in the graph; where the code turns it into a decision, the recorder follows one way, and runs
// the model again until every sequence of decisions has been followed once. Each path is written with its decisions,
// what it returned and its outputs; units.py joins the paths into one datapath with multiplexers, as hardware computes
// every way at once. Identical operations are recorded once (the graph is hash-consed), so the paths share the work
// they have in common.
//
// Three kinds of scalar are recorded, one for each branch of the kernels' code: fixed point with exact products (at
// most 32 bits, ScalarTraits<Fixed>::kExactProducts), fixed point that rounds every operation (wider formats), and
// float. The traits below map each of the format's primitives to one operation of tools/hardware/dataflow.py.
#include <cstdint>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include "hardware/operands.hpp"

namespace pt::hardware::record {

// ---- The graph being recorded ----
struct Node {
  std::string op;
  std::vector<i64> args;
  double value = 0;  // a constant's value
  std::string name;  // an input's name
};

class Recorder {
 public:
  void reset() {
    nodes_.clear();
    index_.clear();
  }
  i64 node(const std::string& op, std::vector<i64> args, double value = 0, const std::string& name = "") {
    auto key = std::make_tuple(op, args, value, name);
    if (auto it = index_.find(key); it != index_.end()) return it->second;
    nodes_.push_back(Node{op, std::move(args), value, name});
    const i64 id = static_cast<i64>(nodes_.size()) - 1;
    index_.emplace(std::move(key), id);
    return id;
  }
  const std::vector<Node>& nodes() const { return nodes_; }

  // Decisions: the script says which way to go at each one, in order; a decision beyond it goes the `true` way and is
  // added. After a run, next_path() makes the script of the next path in depth-first order.
  void begin_path() {
    position_ = 0;
    taken_.clear();
  }
  bool decide(i64 bit) {
    if (position_ == script_.size()) script_.push_back(true);
    const bool way = script_[position_++];
    taken_.emplace_back(bit, way);
    return way;
  }
  bool next_path() {
    script_.resize(position_);
    while (!script_.empty() && !script_.back()) script_.pop_back();
    if (script_.empty()) return false;
    script_.back() = false;
    return true;
  }
  const std::vector<std::pair<i64, bool>>& taken() const { return taken_; }

 private:
  std::vector<Node> nodes_;
  std::map<std::tuple<std::string, std::vector<i64>, double, std::string>, i64> index_;
  std::vector<bool> script_;
  std::size_t position_ = 0;
  std::vector<std::pair<i64, bool>> taken_;
};

Recorder recorder;

// A one-bit value (a comparison, or logic on comparisons). Turning it into a bool is a decision.
struct Bit {
  i64 id;
  operator bool() const { return recorder.decide(id); }  // NOLINT: implicit, as a comparison's result is
  Bit operator!() const { return Bit{recorder.node("not", {id})}; }
  // Both sides are recorded (no short circuit): hardware computes both anyway, and the result is the same.
  friend Bit operator&&(Bit a, Bit b) { return Bit{recorder.node("and", {a.id, b.id})}; }
  friend Bit operator||(Bit a, Bit b) { return Bit{recorder.node("or", {a.id, b.id})}; }
};

enum class Kind { kExactFixed, kRoundedFixed, kFloat };

// A product kept exact (ScalarTraits<Fixed>::Exact): sums, differences, negation and comparisons stay exact; the only
// constant the kernels compare with is 0.
struct Exact {
  i64 id;
  friend Exact operator*(Exact a, Exact b) { return Exact{recorder.node("xmul", {a.id, b.id})}; }
  friend Exact operator+(Exact a, Exact b) { return Exact{recorder.node("xadd", {a.id, b.id})}; }
  friend Exact operator-(Exact a, Exact b) { return Exact{recorder.node("xsub", {a.id, b.id})}; }
  Exact operator-() const { return Exact{recorder.node("xneg", {id})}; }
  static i64 zero(int literal) {
    if (literal != 0) throw std::logic_error("an exact value is compared with a constant other than 0");
    return recorder.node("xzero", {});
  }
  friend Bit operator<(Exact a, Exact b) { return Bit{recorder.node("xlt", {a.id, b.id})}; }
  friend Bit operator<=(Exact a, Exact b) { return Bit{recorder.node("xle", {a.id, b.id})}; }
  friend Bit operator>(Exact a, Exact b) { return b < a; }
  friend Bit operator>=(Exact a, Exact b) { return b <= a; }
  friend Bit operator==(Exact a, Exact b) { return Bit{recorder.node("xeq", {a.id, b.id})}; }
  friend Bit operator!=(Exact a, Exact b) { return !(a == b); }
  friend Bit operator<(Exact a, int b) { return a < Exact{zero(b)}; }
  friend Bit operator<=(Exact a, int b) { return a <= Exact{zero(b)}; }
  friend Bit operator>(Exact a, int b) { return a > Exact{zero(b)}; }
  friend Bit operator>=(Exact a, int b) { return a >= Exact{zero(b)}; }
  friend Bit operator==(Exact a, int b) { return a == Exact{zero(b)}; }
  friend Bit operator!=(Exact a, int b) { return a != Exact{zero(b)}; }
};

// The recorded scalar. Its raw value is its node in the graph, so that operands.hpp's packing (value<T>(raw), raw(v))
// hands the models input nodes and takes output nodes back.
template <Kind K>
struct Traced {
  using Storage = i64;
  i64 raw;
  Traced() : raw(recorder.node("const", {}, 0)) {}
  template <class N, std::enable_if_t<std::is_arithmetic_v<N>, int> = 0>
  explicit Traced(N v) : raw(recorder.node("const", {}, static_cast<double>(v))) {}
  static Traced from_raw(i64 id) {
    Traced t;
    t.raw = id;
    return t;
  }
  static Traced make(const char* op, std::vector<i64> args) { return from_raw(recorder.node(op, std::move(args))); }

  friend Traced operator+(Traced a, Traced b) { return make("add", {a.raw, b.raw}); }
  friend Traced operator-(Traced a, Traced b) { return make("sub", {a.raw, b.raw}); }
  friend Traced operator*(Traced a, Traced b) { return make("mul", {a.raw, b.raw}); }
  friend Traced operator/(Traced a, Traced b) { return make("div", {a.raw, b.raw}); }
  Traced operator-() const { return make("neg", {raw}); }
  Traced& operator+=(Traced o) { return *this = *this + o; }
  Traced& operator-=(Traced o) { return *this = *this - o; }
  Traced& operator*=(Traced o) { return *this = *this * o; }
  Traced& operator/=(Traced o) { return *this = *this / o; }
  friend Bit operator<(Traced a, Traced b) { return Bit{recorder.node("lt", {a.raw, b.raw})}; }
  friend Bit operator<=(Traced a, Traced b) { return Bit{recorder.node("le", {a.raw, b.raw})}; }
  friend Bit operator>(Traced a, Traced b) { return b < a; }
  friend Bit operator>=(Traced a, Traced b) { return b <= a; }
  friend Bit operator==(Traced a, Traced b) { return Bit{recorder.node("eq", {a.raw, b.raw})}; }
  friend Bit operator!=(Traced a, Traced b) { return !(a == b); }
};

}  // namespace pt::hardware::record

namespace pt {

// The primitives of each recorded format, as the format's own traits define them (kernel/fixed_point.hpp,
// kernel/scalar.hpp): each is one operation of dataflow.py, which has the same semantics bit for bit (the testbench
// checks every unit against the real format).
template <hardware::record::Kind K>
struct ScalarTraits<hardware::record::Traced<K>> {
  using T = hardware::record::Traced<K>;
  using Kind = hardware::record::Kind;
  static constexpr bool kFixed = K != Kind::kFloat;
  static T sqrt(T x) { return T::make("sqrt", {x.raw}); }
  static T min(T a, T b) { return T::make("min", {a.raw, b.raw}); }
  static T max(T a, T b) { return T::make("max", {a.raw, b.raw}); }
  static T largest() { return T::make("largest", {}); }
  // Fixed point: 1 / d, which Fixed's operator/ makes the largest value for d = 0. Float nudges a zero d instead; no
  // float unit takes a ray's direction (the box unit is given the reciprocals).
  static T slab_reciprocal(T d) {
    static_assert(kFixed, "the float form of slab_reciprocal is not recorded");
    return T(1) / d;
  }
  static T slab_origin_term(T origin, T reciprocal) { return kFixed ? origin : origin * reciprocal; }
  static T slab_distance(T bound, T reciprocal, T origin_term) {
    return kFixed ? (bound - origin_term) * reciprocal : bound * reciprocal - origin_term;
  }
  static constexpr bool kExactProducts = K == Kind::kExactFixed;
  using Exact = hardware::record::Exact;
  static Exact exact(T x) { return Exact{x.raw}; }  // the same bits, read as a value with F fraction bits
  static T round_exact(Exact v) { return T::make("round", {v.id}); }
  static T exact_sqrt(Exact v) { return T::make("xsqrt", {v.id}); }
  static Exact exact_root(Exact v) { return Exact{hardware::record::recorder.node("xroot", {v.id})}; }
  static T exact_quotient(Exact n, Exact d) { return T::make("quotient", {n.id, d.id}); }
  static T exact_fraction(Exact n, Exact d) { return T::make("fraction", {n.id, d.id}); }
  static T exact_quotient_by_extent(Exact n, T extent) { return T::make("shift_quotient", {n.id, extent.raw}); }
};

}  // namespace pt

namespace pt::hardware::record {

// Whether output k means something only where the unit reports a hit.
template <class Operands>
bool only_on_hit(std::size_t k) {
  if constexpr (requires { Operands::kOnlyOnHit; })
    return Operands::kOnlyOnHit[k];
  else if constexpr (requires { Operands::kAlwaysWritten; })
    return k > 0 && !Operands::kAlwaysWritten;
  else
    return false;
}

std::string quoted(std::string_view s) { return "\"" + std::string(s) + "\""; }

// One unit in one kind of scalar, as a JSON object.
template <class Operands, Kind K>
std::string record_unit() {
  using T = Traced<K>;
  constexpr std::size_t kIn = Operands::kInputs.size(), kOut = Operands::kOutputs.size();
  const bool has_hit = Operands::kOutputs[0] == "hit";
  recorder.reset();
  i64 inputs[kIn];
  for (std::size_t k = 0; k < kIn; ++k) inputs[k] = recorder.node("input", {}, 0, std::string(Operands::kInputs[k]));
  std::string paths;
  do {
    recorder.begin_path();
    i64 out[kOut];
    Operands::template model<T>(inputs, out);
    std::string path = "{\"decisions\": [";
    for (std::size_t k = 0; k < recorder.taken().size(); ++k)
      path += (k ? ", [" : "[") + std::to_string(recorder.taken()[k].first) + ", " + (recorder.taken()[k].second ? "1" : "0") + "]";
    path += "], \"returned\": " + std::string(!has_hit || out[0] ? "1" : "0") + ", \"outputs\": [";
    for (std::size_t k = has_hit ? 1 : 0; k < kOut; ++k) path += (k > (has_hit ? 1u : 0u) ? ", " : "") + std::to_string(out[k]);
    paths += (paths.empty() ? "" : ",\n      ") + path + "]}";
  } while (recorder.next_path());
  std::string text = "{\"inputs\": [";
  for (std::size_t k = 0; k < kIn; ++k) text += (k ? ", [" : "[") + quoted(Operands::kInputs[k]) + ", " + std::to_string(inputs[k]) + "]";
  text += "],\n    \"has_hit\": " + std::string(has_hit ? "true" : "false") + ", \"outputs\": [";
  for (std::size_t k = has_hit ? 1 : 0; k < kOut; ++k)
    text += (k > (has_hit ? 1u : 0u) ? ", [" : "[") + quoted(Operands::kOutputs[k]) + ", " +
            (only_on_hit<Operands>(k) ? "true" : "false") + "]";
  text += "],\n    \"nodes\": [";
  const auto& nodes = recorder.nodes();
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    text += (k ? ",\n      [" : "\n      [") + quoted(nodes[k].op) + ", [";
    for (std::size_t a = 0; a < nodes[k].args.size(); ++a) text += (a ? ", " : "") + std::to_string(nodes[k].args[a]);
    char value[32];
    std::snprintf(value, sizeof value, "%.17g", nodes[k].value);
    text += "], " + std::string(value) + ", " + quoted(nodes[k].name) + "]";
  }
  text += "],\n    \"paths\": [\n      " + paths + "]}";
  return text;
}

template <Kind K>
std::string record_kind(bool engine_units) {
  std::string text = "{\n  \"box\": " + record_unit<BoxOperands, K>() + ",\n  \"triangle\": " + record_unit<TriangleOperands, K>() +
                     ",\n  \"quad\": " + record_unit<QuadOperands, K>() + ",\n  \"sphere\": " + record_unit<SphereOperands, K>();
  if constexpr (K != Kind::kFloat) {
    if (engine_units)
      text += ",\n  \"ray_setup\": " + record_unit<RaySetupOperands, K>() + ",\n  \"moving_sphere\": " + record_unit<MovingSphereOperands, K>() +
              ",\n  \"instance_ray\": " + record_unit<InstanceRayOperands, K>() +
              ",\n  \"sphere_crossings\": " + record_unit<SphereCrossingsOperands, K>() + ",\n  \"medium\": " + record_unit<MediumOperands, K>();
  }
  return text + "}";
}

}  // namespace pt::hardware::record

int main() {
  using pt::hardware::record::Kind;
  using pt::hardware::record::record_kind;
  std::printf("{\"exact_fixed\": %s,\n\"rounded_fixed\": %s,\n\"float\": %s}\n", record_kind<Kind::kExactFixed>(true).c_str(),
              record_kind<Kind::kRoundedFixed>(true).c_str(), record_kind<Kind::kFloat>(false).c_str());
  return 0;
}
