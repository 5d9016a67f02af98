// The Verilator testbenches of the intersection units, one per unit and format, in one program (so that Verilator's
// runtime is compiled once):
//
//   pt_record_operands --unit box --format q16.16 ... | pt_hardware_testbench box_q16_16 --min-recorded 1000000
//   pt_hardware_testbench box_q16_16 --edge-cases-only
#include <cstdio>
#include <cstring>

#include "testbench_entries.hpp"  // generated: the units and formats built, and their entries

int main(int argc, char** argv) {
  if (argc >= 2)
    for (const TestbenchEntry& entry : kTestbenchEntries)
      if (std::strcmp(entry.name, argv[1]) == 0) return entry.run(argc - 1, argv + 1);
  std::fprintf(stderr, "usage: %s UNIT_FORMAT [--min-recorded N] [--edge-cases-only] < operand stream\nunits and formats built:", argv[0]);
  for (const TestbenchEntry& entry : kTestbenchEntries) std::fprintf(stderr, " %s", entry.name);
  std::fprintf(stderr, "\n");
  return 2;
}
