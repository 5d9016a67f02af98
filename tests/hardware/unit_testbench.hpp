// Verilator testbench of one intersection unit in one format: feeds the pipelined unit one operand set per clock
// (edge cases made here, then the sets recorded from renders, read from stdin) and compares every output bit with
// the C++ model, the kernel function on Fixed<I, F> (or float) called on the same operands.
//
// Included once per unit and format by a generated source that defines PT_UNIT_PORTS (the generated port binding
// header), PT_UNIT_BINDING (its namespace), PT_UNIT_OPERANDS (the unit's entry in hardware/operands.hpp),
// PT_INTEGER_BITS, PT_FRACTION_BITS (both 0 for float32, which PT_FLOAT32 selects), PT_TESTBENCH_ENTRY (the name of
// the function it defines; hardware_testbench.cpp picks one by unit and format) and PT_TESTBENCH_NAMESPACE (where its own definitions go, so that a unity build may
// put several testbenches in one source: this file has no include guard on purpose).
// The entry returns non-zero on any difference, or when fewer recorded sets arrive than asked for.
// float32: the model runs with denormals flushed to zero on input and output (MXCSR's DAZ and FTZ bits, set for the
// testbench's run), the policy of the float32 operators (tools/hardware/float32.py), and any NaN equals any NaN (the
// units give one canonical NaN, x86 propagates payloads); every other value is compared bit for bit. The kernel is
// compiled without contraction into fused multiply-adds (-ffp-contract=off, set for all host code): the model does
// each multiply and add apart, rounded, as the unit does.
#include <cfloat>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <random>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include <verilated.h>
#include <xmmintrin.h>

#include "hardware/operands.hpp"
#include PT_UNIT_PORTS

namespace pt::hardware {
namespace PT_TESTBENCH_NAMESPACE {

#ifdef PT_FLOAT32
using T = float;
#else
using T = Fixed<PT_INTEGER_BITS, PT_FRACTION_BITS>;
#endif
constexpr bool kFloat = std::is_same_v<T, float>;
using Operands = PT_UNIT_OPERANDS;
using Ports = PT_UNIT_BINDING::UnitPorts;
constexpr int kInputs = static_cast<int>(Operands::kInputs.size());
constexpr int kOutputs = static_cast<int>(Operands::kOutputs.size());

// The range's end and one as raw values (a float's bits), and the largest value and smallest step as doubles.
template <class U>
constexpr i64 max_raw() {
  if constexpr (std::is_same_v<U, float>)
    return 0x7f7fffff;
  else
    return U::kMaxRaw;
}
template <class U>
constexpr i64 one_raw() {
  if constexpr (std::is_same_v<U, float>)
    return 0x3f800000;
  else
    return i64(1) << U::kFractionBits;
}
template <class U>
constexpr int total_bits() {
  if constexpr (std::is_same_v<U, float>)
    return 32;
  else
    return U::kTotalBits;
}
constexpr i64 kMax = max_raw<T>();
constexpr i64 kOne = one_raw<T>();
const double kLargest = kFloat ? static_cast<double>(FLT_MAX) : static_cast<double>(kMax) / static_cast<double>(kOne);
const double kStep = kFloat ? static_cast<double>(FLT_MIN) : 1.0 / static_cast<double>(kOne);
const std::string kFormat = kFloat ? std::string("float32") : "q" + std::to_string(PT_INTEGER_BITS) + "." + std::to_string(PT_FRACTION_BITS);

static_assert(sizeof(Ports::kInputs) / sizeof(Ports::kInputs[0]) == kInputs, "the unit's inputs are not the operand layout's");
static_assert(sizeof(Ports::kOutputs) / sizeof(Ports::kOutputs[0]) == kOutputs, "the unit's outputs are not the operand layout's");

i64 raw_of(double v) { return raw(T(v)); }
const i64 kNegMax = raw_of(-kLargest);
const i64 kTwo = raw_of(2.0);

// The value `steps` raw steps away: the next representable values (for float, towards the infinities).
template <class U>
U nudged(U v, int steps) {
  if constexpr (std::is_same_v<U, float>) {
    for (; steps > 0; --steps) v = std::nextafter(v, FLT_MAX);
    for (; steps < 0; ++steps) v = std::nextafter(v, -FLT_MAX);
    return v;
  } else {
    return value<U>(raw(v) + steps);
  }
}

// Outputs agree: the same raw value, or (float32) both NaN.
bool same_output(i64 hardware, i64 model) {
  if constexpr (kFloat) {
    if (std::isnan(value<float>(hardware)) && std::isnan(value<float>(model))) return true;
  }
  return hardware == model;
}

// ---- Edge cases ----
// Operand sets away from what renders produce: the range's ends, zero divisors, rays along the axes, rays grazing a
// surface or a sphere, exact boundary values. Each unit has structured cases; all get random sets drawn from a
// list of extreme values.
struct EdgeCases {
  std::vector<i64> sets;
  std::mt19937_64 rng{19};
  void add(const std::vector<i64>& set) {
    if (static_cast<int>(set.size()) != kInputs) throw std::logic_error("an edge case of the wrong size");
    for (i64 v : set) sets.push_back(kFloat ? v : std::max(-kMax, std::min(kMax, v)));
  }
  i64 extreme() {
    if constexpr (kFloat) return extreme_float();
    static const i64 kValues[] = {0,    1,     -1,       2,         -2,       kOne,      -kOne,    kOne - 1,  kOne + 1, -kOne + 1,
                                  kMax, -kMax, kMax - 1, -kMax + 1, kMax / 2, -kMax / 2, kOne / 2, -kOne / 2, kOne * 2, -kOne * 2};
    std::uniform_int_distribution<int> pick(0, sizeof(kValues) / sizeof(kValues[0]) + 3);
    const int k = pick(rng);
    if (k < static_cast<int>(sizeof(kValues) / sizeof(kValues[0]))) return kValues[k];
    if (k == static_cast<int>(sizeof(kValues) / sizeof(kValues[0]))) return std::uniform_int_distribution<i64>(-kMax, kMax)(rng);
    return std::uniform_int_distribution<i64>(-4 * kOne, 4 * kOne)(rng);  // around the unit-size values of directions
  }
  // Floats: zeros of both signs, denormals (read as zero), the ends of the normal range, infinities, NaN, values
  // next to 1, very large and very small ones, random bit patterns and random values of the size of directions.
  i64 extreme_float() {
    static const float kValues[] = {0.0f,
                                    -0.0f,
                                    1.0f,
                                    -1.0f,
                                    0.5f,
                                    -0.5f,
                                    2.0f,
                                    -2.0f,
                                    FLT_MAX,
                                    -FLT_MAX,
                                    FLT_MIN,
                                    -FLT_MIN,
                                    value<float>(1),
                                    value<float>(0x007fffff),
                                    value<float>(0x80000001),
                                    INFINITY,
                                    -INFINITY,
                                    value<float>(0x7fc00000),
                                    1e-20f,
                                    -1e-20f,
                                    1e20f,
                                    -1e20f,
                                    1e-30f,
                                    1e30f,
                                    -1e30f,
                                    value<float>(0x3f7fffff),
                                    value<float>(0x3f800001),
                                    3.0f,
                                    1e-3f,
                                    1e3f};
    constexpr int kCount = sizeof(kValues) / sizeof(kValues[0]);
    const int k = std::uniform_int_distribution<int>(0, kCount + 3)(rng);
    if (k < kCount) return raw(kValues[k]);
    if (k == kCount) return static_cast<std::int32_t>(static_cast<std::uint32_t>(rng()));
    return raw(std::uniform_real_distribution<float>(-4.0f, 4.0f)(rng));
  }
  void random_extremes(int count) {
    std::vector<i64> set(kInputs);
    for (int n = 0; n < count; ++n) {
      for (i64& v : set) v = extreme();
      // A quad's extents are powers of two wherever flatten_scene makes them: any power within the range.
      // (Float stores extents of 1, ScalarTraits<float>::quad_extent.)
      for (int k = Operands::kFirstExtent; k < Operands::kFirstExtent + Operands::kExtents; ++k)
        set[k] = kFloat ? kOne : i64(1) << std::uniform_int_distribution<int>(0, total_bits<T>() - 3)(rng);
      add(set);
    }
  }
};

// Unit directions along and near the axes, and random ones, in the format.
std::vector<Vec3<T>> test_directions(std::mt19937_64& rng) {
  std::vector<Vec3<T>> dirs;
  for (int axis = 0; axis < 3; ++axis)
    for (double s : {1.0, -1.0}) {
      Vec3<double> d{0, 0, 0};
      (axis == 0 ? d.x : axis == 1 ? d.y : d.z) = s;
      dirs.push_back(Vec3<T>{T(d.x), T(d.y), T(d.z)});
      // One step off the axis: reciprocals at the ends of the range.
      Vec3<T> off_axis{T(d.x), T(d.y), T(d.z)};
      off_axis.x = nudged(off_axis.x, axis == 0 ? 0 : 1);
      off_axis.y = nudged(off_axis.y, axis == 1 ? 0 : -1);
      dirs.push_back(off_axis);
    }
  std::normal_distribution<double> gauss;
  for (int n = 0; n < 20; ++n) {
    const double x = gauss(rng), y = gauss(rng), z = gauss(rng), len = std::sqrt(x * x + y * y + z * z);
    dirs.push_back(Vec3<T>{T(x / len), T(y / len), T(z / len)});
  }
  return dirs;
}

void push3(std::vector<i64>& set, const Vec3<T>& v) { set.push_back(raw(v.x)), set.push_back(raw(v.y)), set.push_back(raw(v.z)); }

void unit_edge_cases(EdgeCases& e, BoxOperands) {
  std::mt19937_64 rng(3);
  const double lengths[] = {0.0, kStep, 0.5, 1.0, 3.0, kLargest / 4};
  for (const Vec3<T>& d : test_directions(rng))
    for (double half : lengths)
      for (double offset : {-2.0, 0.0, 0.5, 2.0}) {
        // A box of half-size `half` around (offset, 0, 0); the ray from the origin, planes picked as make_box_ray does.
        Ray<T> ray{Vec3<T>{}, d, T(0)};
        const BoxRay<T> r = make_box_ray(ray);
        BvhNode<T> node{};
        node.lo = Vec3<T>{T(offset - half), T(-half), T(-half)};
        node.hi = Vec3<T>{T(offset + half), T(half), T(half)};
        for (i64 t_max : {kMax, kOne, i64(0)}) {
          std::vector<i64> set(kInputs);
          BoxOperands::pack(r, node, T(0), value<T>(t_max), set.data());
          e.add(set);
        }
      }

  if constexpr (kFloat) {
    // Products at the bottom of the normal range: 2^-62 (1 + 2^-23) times 2^-65 (2 - 2^-22) is 2^-126 (1 - 2^-46),
    // below 2^-126 but rounding up to it, which FTZ keeps (x86 judges tininess after rounding); with the neighbours
    // of both factors, of both signs.
    for (i64 bound : {0x20800000, 0x20800001, 0x20800002})
      for (i64 reciprocal : {0x1f7ffffd, 0x1f7ffffe, 0x1f7fffff, 0x1f800000})
        for (i64 sign : {i64(0), i64(INT32_MIN)}) {
          const i64 inv = reciprocal | sign;
          e.add({inv, inv, inv, 0, 0, 0, bound, bound, bound, bound + 0x00800000, bound + 0x00800000, bound + 0x00800000, kNegMax, kMax});
        }
  }
}

void unit_edge_cases(EdgeCases& e, TriangleOperands) {
  std::mt19937_64 rng(5);
  const Vec3<T> p0{T(-1.0), T(-1.0), T(2.0)}, e1{T(2.0), T(0.0), T(0.0)}, e2{T(0.0), T(2.0), T(0.0)};
  for (const Vec3<T>& d : test_directions(rng)) {
    // Rays in the triangle's plane (det = 0), from its corners and edges (b1 = 0, b1 + b2 = 1), and from inside it.
    for (const Vec3<T>& o : {Vec3<T>{}, Vec3<T>{T(-1.0), T(-1.0), T(2.0)}, Vec3<T>{T(0.0), T(0.0), T(2.0)}, Vec3<T>{T(1.0), T(-1.0), T(0.0)},
                             Vec3<T>{T(-1.0), T(0.0), T(0.0)}, Vec3<T>{T(0.0), T(0.0), T(-1.0)}}) {
      for (i64 t_min : {i64(0), kNegMax, kTwo}) {
        std::vector<i64> set;
        push3(set, p0), push3(set, e1), push3(set, e2), push3(set, o), push3(set, d);
        set.push_back(t_min), set.push_back(kMax);
        e.add(set);
      }
    }
  }
  // A triangle with edges one step long (det rounds to zero) and one with huge edges (products saturate).
  for (const Vec3<T>& d : test_directions(rng))
    for (i64 size : {i64(1), kMax, kMax / 3}) {
      std::vector<i64> set;
      push3(set, Vec3<T>{});
      set.insert(set.end(), {size, 0, 0, 0, size, 0});
      push3(set, Vec3<T>{T(0.0), T(0.0), T(-1.0)});
      push3(set, d);
      set.push_back(0), set.push_back(kMax);
      e.add(set);
    }
}

void unit_edge_cases(EdgeCases& e, QuadOperands) {
  std::mt19937_64 rng(7);
  // Square quads in z = 0 of side 1, 1/16 and 64 (normal +z, du and dv along x and y, times the extent the kernel's
  // traits pick for the side), rays along and across them, from their corners and edges.
  for (double size : {1.0, 1.0 / 16, 64.0})
    for (const Vec3<T>& d : test_directions(rng))
      for (const Vec3<T>& o : {Vec3<T>{T(0.5 * size), T(0.5 * size), T(1.0)}, Vec3<T>{T(0.0), T(0.0), T(-1.0)}, Vec3<T>{T(size), T(size), T(0.0)},
                               Vec3<T>{T(0.0), T(0.0), T(0.0)}}) {
        const double extent = ScalarTraits<T>::quad_extent(size);
        std::vector<i64> set;
        push3(set, Vec3<T>{}), push3(set, Vec3<T>{T(0.0), T(0.0), T(1.0)});
        push3(set, Vec3<T>{T(extent / size), T(0.0), T(0.0)}), push3(set, Vec3<T>{T(0.0), T(extent / size), T(0.0)});
        set.push_back(raw_of(extent)), set.push_back(raw_of(extent));
        push3(set, o), push3(set, d);
        set.push_back(0), set.push_back(kMax);
        e.add(set);
        set[set.size() - 2] = kNegMax;  // the whole line, as a medium's boundary is tested
        e.add(set);
      }
}

void unit_edge_cases(EdgeCases& e, SphereOperands) {
  std::mt19937_64 rng(11);
  // Rays through the centre, tangent (grazing: discriminant zero), just missing, from inside, and spheres whose
  // squared radius saturates.
  for (const Vec3<T>& d : test_directions(rng))
    for (double radius : {1.0, 0.25, kStep, kLargest / 2})
      for (int where = 0; where < 4; ++where) {
        Vec3<T> center{T(0.0), T(0.0), T(0.0)};
        const Vec3<T> origin{T(0.0), T(0.0), T(0.0)};
        if (where > 0) {
          // Off the ray's line by the radius (tangent: a grazing ray), a step more, a step less; from the origin
          // otherwise (inside the sphere).
          const Vec3<T> axis = std::abs(static_cast<double>(d.x)) < 0.9 ? Vec3<T>{T(1.0), T(0.0), T(0.0)} : Vec3<T>{T(0.0), T(1.0), T(0.0)};
          const Vec3<T> side = normalize(cross(d, axis));  // perpendicular to the ray
          const T off = nudged(T(radius), where == 1 ? 0 : where == 2 ? 1 : -1);
          center = side * off + d * T(2.0);
        }
        std::vector<i64> set;
        push3(set, center), set.push_back(raw_of(radius)), push3(set, origin), push3(set, d);
        set.push_back(0), set.push_back(kMax);
        e.add(set);
      }
}

// ---- Running the pipeline ----
struct Bench {
  VerilatedContext context;
  Ports::Model* model;
  std::deque<std::vector<i64>> in_flight;  // operand sets whose results are still in the pipeline
  std::size_t compared = 0, mismatches = 0;
  Bench() { model = new Ports::Model(&context); }
  ~Bench() {
    model->final();
    delete model;
  }

  void clock() {
    model->clk = 0;
    model->eval();
    model->clk = 1;
    model->eval();
  }
  // One clock: the set (or nothing) enters, and a result that leaves is checked against the model.
  void step(const i64* set) {
    model->in_valid = set != nullptr;
    if (set) {
      Ports::set_inputs(*model, set);
      in_flight.emplace_back(set, set + kInputs);
    }
    clock();
    if (model->out_valid) check();
  }
  void check() {
    if (in_flight.empty()) throw std::logic_error("the unit gave a result nobody asked for");
    const std::vector<i64> set = std::move(in_flight.front());
    in_flight.pop_front();
    i64 hardware[kOutputs], expected[kOutputs];
    Ports::get_outputs(*model, reinterpret_cast<long long*>(hardware));
    Operands::model<T>(set.data(), expected);
    ++compared;
    bool same = hardware[0] == expected[0];
    if (expected[0] || Operands::kAlwaysWritten)
      for (int k = 1; k < kOutputs; ++k) same = same && same_output(hardware[k], expected[k]);
    if (same) return;
    if (++mismatches <= 10) {
      std::fprintf(stderr, "MISMATCH %s %s, operand set %zu:", std::string(Operands::kName).c_str(), kFormat.c_str(), compared);
      for (int k = 0; k < kInputs; ++k) std::fprintf(stderr, " %s=%" PRId64, std::string(Operands::kInputs[k]).c_str(), set[k]);
      std::fprintf(stderr, "\n  model:   ");
      for (int k = 0; k < kOutputs; ++k) std::fprintf(stderr, " %s=%" PRId64, std::string(Operands::kOutputs[k]).c_str(), expected[k]);
      std::fprintf(stderr, "\n  hardware:");
      for (int k = 0; k < kOutputs; ++k) std::fprintf(stderr, " %s=%" PRId64, std::string(Operands::kOutputs[k]).c_str(), hardware[k]);
      std::fprintf(stderr, "\n");
    }
  }
  void drain() {
    for (int k = 0; k <= Ports::kLatency + 1 && !in_flight.empty(); ++k) step(nullptr);
    if (!in_flight.empty()) throw std::logic_error("results are missing after the pipeline's latency");
  }
};

int run_testbench(int argc, char** argv) {
  std::size_t min_recorded = 0;
  bool read_recorded = true;
  bool ieee_denormals = false;  // float32: run the model with denormals (MXCSR as it was), to show the edge cases reach them
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--min-recorded" && i + 1 < argc)
      min_recorded = std::stoull(argv[++i]);
    else if (arg == "--edge-cases-only")
      read_recorded = false;
    else if (arg == "--ieee-denormals")
      ieee_denormals = true;
    else
      throw std::runtime_error("usage: " + std::string(argv[0]) + " [--min-recorded N] [--edge-cases-only] [--ieee-denormals] < operand stream");
  }
  for (int k = 0; k < kInputs; ++k)
    if (Operands::kInputs[k] != Ports::kInputs[k])
      throw std::runtime_error("input " + std::to_string(k) + " of the unit is " + Ports::kInputs[k] + ", the operand layout has " +
                               std::string(Operands::kInputs[k]));
  // The float32 model's denormal policy, the unit's (restored on return).
  struct FlushDenormals {
    unsigned saved = _mm_getcsr();
    explicit FlushDenormals(bool flush) {
      if (flush) _mm_setcsr(saved | _MM_FLUSH_ZERO_ON | 0x0040 /* DAZ */);
    }
    ~FlushDenormals() { _mm_setcsr(saved); }
  } flush_denormals(kFloat && !ieee_denormals);
  Bench bench;
  bench.clock();  // the valid chain starts empty

  EdgeCases edges;
  unit_edge_cases(edges, Operands{});
  const std::size_t structured = edges.sets.size() / kInputs;
  edges.random_extremes(100000);
  const std::size_t edge_count = edges.sets.size() / kInputs;
  for (std::size_t n = 0; n < edge_count; ++n) bench.step(edges.sets.data() + n * kInputs);
  bench.drain();
  const std::size_t edge_mismatches = bench.mismatches;

  std::size_t recorded = 0;
  if (read_recorded) {
    StreamHeader header;
    if (std::fread(&header, sizeof header, 1, stdin) != 1 || std::memcmp(header.magic, kStreamMagic, sizeof header.magic) != 0)
      throw std::runtime_error("no operand stream on stdin (pt_record_operands writes one)");
    if (std::string(header.unit) != Operands::kName || header.integer_bits != PT_INTEGER_BITS || header.fraction_bits != PT_FRACTION_BITS ||
        header.values != kInputs)
      throw std::runtime_error("the operand stream is for " + std::string(header.unit) + " q" + std::to_string(header.integer_bits) + "." +
                               std::to_string(header.fraction_bits) + " (q0.0: float32), not this unit");
    std::vector<i64> buffer(static_cast<std::size_t>(kInputs) * 4096);
    while (true) {
      const std::size_t got = std::fread(buffer.data(), sizeof(i64) * kInputs, 4096, stdin);
      for (std::size_t n = 0; n < got; ++n) bench.step(buffer.data() + n * kInputs);
      recorded += got;
      if (got < 4096) break;
    }
    bench.drain();
  }
  std::printf(
      "%s unit %s (%d-clock pipeline): %zu edge-case operand sets (%zu structured, %zu from extreme values), %zu recorded from "
      "renders; %zu compared, %zu mismatches (%zu in the edge cases)\n",
      std::string(Operands::kName).c_str(), kFormat.c_str(), Ports::kLatency, edge_count, structured, edge_count - structured, recorded,
      bench.compared, bench.mismatches, edge_mismatches);
  if (bench.mismatches > 0) return 1;
  if (recorded < min_recorded) {
    std::fprintf(stderr, "only %zu recorded operand sets, %zu asked for\n", recorded, min_recorded);
    return 1;
  }
  return 0;
}

}  // namespace PT_TESTBENCH_NAMESPACE

int PT_TESTBENCH_ENTRY(int argc, char** argv) { return PT_TESTBENCH_NAMESPACE::run_testbench(argc, argv); }

}  // namespace pt::hardware

#undef PT_UNIT_PORTS
#undef PT_UNIT_BINDING
#undef PT_UNIT_OPERANDS
#undef PT_INTEGER_BITS
#undef PT_FRACTION_BITS
#undef PT_FLOAT32
#undef PT_TESTBENCH_ENTRY
#undef PT_TESTBENCH_NAMESPACE
