# IEEE-754 binary32 operators for the dataflow graphs of dataflow.py: a FloatUnit builds the same unit descriptions
# (tools/hardware/units.py) on float32 values, with the semantics of the C++ kernel's `float` instantiation as the
# testbench runs it, so that the float datapath can be verified bit for bit and synthesised beside the fixed formats.
#
# Semantics of each operation (round to nearest, ties to even, throughout):
#   add, sub   3 clocks: order the operands by magnitude, align the smaller with guard, round and sticky bits, add or
#              subtract, normalise, round
#   mul        3 clocks: the 24 x 24-bit significand product, normalise, round
#   div        2 + ceil(26 / K) clocks: restoring division of the significands, one quotient bit per step, K steps per
#              stage, then round with the remainder as the sticky bit
#   sqrt       2 + ceil(25 / K) clocks: the root digit by digit, K digits per stage, then round
#   lt, le, eq 1 clock: IEEE comparisons (false where an operand is NaN; +0 equals -0)
#   min, max   1 clock: a < b ? a : b and a > b ? a : b, as ScalarTraits<float>::min and max (the operand chosen,
#              so that a NaN goes through where the C++ lets it)
#   neg        1 clock: the sign bit flipped (as the compiler's XOR with the sign mask)
#   select     1 clock: c ? a : b
# Denormals: flushed to zero on input and output (FTZ and DAZ, as GPUs do under fast math and x86 does with MXCSR's
# FTZ and DAZ bits set, which the testbench sets before calling the kernel). An input with a zero exponent is read as
# a zero of its sign (min and max give it so, as x86's minss and maxss do under DAZ); a result whose exponent after
# rounding (unbounded) is below the normal range is a zero of the result's sign. Supporting denormals would need a
# normalising shift on each multiplier input and a denormalising one on each output.
# Infinities follow IEEE-754 (overflow rounds to infinity, as round to nearest does). Every NaN result is the
# canonical quiet NaN 0x7fc00000; x86 returns the first NaN operand or its own default NaN 0xffc00000 instead, so the
# testbench counts any NaN as equal to any NaN and compares every other value bit for bit.

from __future__ import annotations

from dataflow import Emitter, Unit, Value

ONE = 0x3F800000
NAN = 0x7FC00000
ADD_LATENCY = 3
MUL_LATENCY = 3


class FloatUnit(Unit):
    """A unit on binary32 values. The fixed-point `fault` option becomes: products truncated instead of rounded to
    nearest even."""

    is_float = True

    def __init__(self, name: str, divide_steps_per_stage: int = 1, root_steps_per_stage: int = 1, fault: str = ""):
        # Not Unit.__init__: that one checks a fixed-point format. The fields the graph and its emitter read:
        self.name = name
        self.I, self.F, self.W = 0, 0, 32
        self.max_raw = (1 << 31) - 1
        self.divide_steps = divide_steps_per_stage
        self.root_steps = root_steps_per_stage
        if fault not in ("", "truncate-products"):
            raise ValueError(f"unknown fault {fault!r}")
        self.fault = fault
        self.values = []
        self.inputs = []
        self.outputs = []

    @property
    def module_name(self) -> str:
        return f"{self.name}_unit_float32"

    @property
    def format_name(self) -> str:
        return "float32"

    @property
    def model_type(self) -> str:
        return "float (denormals flushed to zero: MXCSR FTZ and DAZ)"

    def divide_latency(self, quotient_bits: int | None = None) -> int:
        return 2 + -(-26 // self.divide_steps)

    def root_latency(self, radicand_bits: int | None = None) -> int:
        return 2 + -(-25 // self.root_steps)

    def const(self, bits: int) -> Value:
        assert 0 <= bits < (1 << 32)
        return self._value("const", (), self.W, 0, bits)

    def one(self): return self.const(ONE)
    def zero(self): return self.const(0)

    def add(self, a, b): self._fixed(a, b); return self._value("add", (a, b), self.W, ADD_LATENCY)
    def sub(self, a, b): self._fixed(a, b); return self._value("sub", (a, b), self.W, ADD_LATENCY)
    def mul(self, a, b): self._fixed(a, b); return self._value("mul", (a, b), self.W, MUL_LATENCY)
    def div(self, a, b): self._fixed(a, b); return self._value("div", (a, b), self.W, self.divide_latency())
    def sqrt(self, a): self._fixed(a); return self._value("sqrt", (a,), self.W, self.root_latency())

    def _no_exact(self, *args, **kwargs):
        raise TypeError("float32 units round every operation: the exact operations are for fixed point")

    xmul = xadd = xsub = xlt = xle = xgt = xge = xeq = xzero = round_exact = exact_sqrt = quotient = shift_quotient = _no_exact

    def verilog(self) -> str:
        return FloatEmitter(self).emit()


class FloatEmitter(Emitter):
    """The dataflow emitter with the float32 operators: arithmetic as submodules, compares as functions."""

    def emit_value(self, v) -> None:
        u = self.u
        a = [self.ref(x, v.start) for x in v.args]
        n = v.name
        if v.op in ("input", "const"):
            return
        if v.op in ("add", "sub"):
            module = self.module(add_module)
            b = a[1] if v.op == "add" else f"{{~{a[1]}[31], {a[1]}[30:0]}}"  # a - b is a + (-b), exactly
            self.decls.append(f"  wire [31:0] {n};")
            self.decls.append(f"  {module} {n}_adder(.clk(clk), .a({a[0]}), .b({b}), .sum({n}));")
        elif v.op == "mul":
            module = self.module(mul_module, u.fault == "truncate-products")
            self.decls.append(f"  wire [31:0] {n};")
            self.decls.append(f"  {module} {n}_multiplier(.clk(clk), .a({a[0]}), .b({a[1]}), .product({n}));")
        elif v.op == "div":
            module = self.module(div_module, u.divide_steps)
            self.decls.append(f"  wire [31:0] {n};")
            self.decls.append(f"  {module} {n}_divider(.clk(clk), .a({a[0]}), .b({a[1]}), .quotient({n}));")
        elif v.op == "sqrt":
            module = self.module(sqrt_module, u.root_steps)
            self.decls.append(f"  wire [31:0] {n};")
            self.decls.append(f"  {module} {n}_root(.clk(clk), .a({a[0]}), .root({n}));")
        elif v.op in ("lt", "le", "eq"):
            self.uses_compare = True
            self.decls.append(f"  reg {n};")
            self.body.append(f"    {n} <= float32_{v.op}({a[0]}, {a[1]});")
        elif v.op in ("min", "max"):
            self.uses_compare = True
            self.decls.append(f"  reg [31:0] {n};")
            first, second = (a[0], a[1]) if v.op == "min" else (a[1], a[0])
            self.body.append(f"    {n} <= float32_flushed(float32_lt({first}, {second}) ? {a[0]} : {a[1]});")
        elif v.op == "neg":
            self.decls.append(f"  reg [31:0] {n};")
            self.body.append(f"    {n} <= {{~{a[0]}[31], {a[0]}[30:0]}};")
        elif v.op == "select":
            self.decls.append(f"  reg [31:0] {n};")
            self.body.append(f"    {n} <= {a[0]} ? {a[1]} : {a[2]};")
        elif v.op in ("and", "or", "not"):
            super().emit_value(v)
        else:
            raise AssertionError(f"{v.op} is not a float32 operation")

    def emit(self) -> str:
        self.uses_compare = False
        text = super().emit()
        if self.uses_compare:
            # The compare functions go inside the unit's module, before its first declaration.
            marker = "  // Which stages hold a valid operand set."
            text = text.replace(marker, COMPARE_FUNCTIONS + marker, 1)
        return text


# Comparisons of binary32 values with denormals read as zero: NaN compares false, +0 equals -0.
COMPARE_FUNCTIONS = """  // IEEE-754 comparisons of binary32 values (denormals read as zero).
  function float32_nan(input [31:0] x);
    float32_nan = (x[30:23] == 8'hff) && (x[22:0] != 23'd0);
  endfunction
  function [31:0] float32_flushed(input [31:0] x);
    float32_flushed = (x[30:23] == 8'd0) ? {x[31], 31'd0} : x;
  endfunction
  function [30:0] float32_magnitude(input [31:0] x);
    float32_magnitude = (x[30:23] == 8'd0) ? 31'd0 : x[30:0];
  endfunction
  function float32_lt(input [31:0] a, input [31:0] b);
    reg [30:0] ma, mb;
    begin
      ma = float32_magnitude(a);
      mb = float32_magnitude(b);
      if (float32_nan(a) || float32_nan(b)) float32_lt = 1'b0;
      else if (a[31] != b[31]) float32_lt = a[31] && (ma != 31'd0 || mb != 31'd0);
      else if (a[31]) float32_lt = ma > mb;
      else float32_lt = ma < mb;
    end
  endfunction
  function float32_eq(input [31:0] a, input [31:0] b);
    reg [30:0] ma, mb;
    begin
      ma = float32_magnitude(a);
      mb = float32_magnitude(b);
      float32_eq = !float32_nan(a) && !float32_nan(b) && ma == mb && (a[31] == b[31] || ma == 31'd0);
    end
  endfunction
  function float32_le(input [31:0] a, input [31:0] b);
    float32_le = float32_lt(a, b) || float32_eq(a, b);
  endfunction
"""

# Rounding a normalised significand (24 bits, the leading one at the top) with its guard and sticky bits to nearest
# even, and packing the result with overflow to infinity and flush to zero. The exponent is signed and unbounded
# (12 bits), so that a carry out of the rounding is seen before the range is checked: overflow and tininess are
# judged after rounding, as x86 does (a product just below 2^-126 that rounds up to it is 2^-126, not zero).
ROUND_FUNCTION = """  function [31:0] float32_round(input sign, input signed [11:0] exponent, input [23:0] significand, input guard,
                                input sticky, input truncate);
    reg [24:0] rounded;
    reg signed [11:0] e;
    begin
      rounded = {1'b0, significand} + ((!truncate && guard && (sticky || significand[0])) ? 25'd1 : 25'd0);
      e = rounded[24] ? exponent + 12'sd1 : exponent;
      if (e >= 12'sd255) float32_round = {sign, 8'hff, 23'd0};
      else if (e <= 12'sd0) float32_round = {sign, 31'd0};
      else float32_round = {sign, e[7:0], rounded[24] ? rounded[23:1] : rounded[22:0]};
    end
  endfunction
"""

CLASSIFY = """  wire a_zero = (a[30:23] == 8'd0), a_inf = (a[30:23] == 8'hff) && (a[22:0] == 23'd0), a_nan = (a[30:23] == 8'hff) && (a[22:0] != 23'd0);
  wire b_zero = (b[30:23] == 8'd0), b_inf = (b[30:23] == 8'hff) && (b[22:0] == 23'd0), b_nan = (b[30:23] == 8'hff) && (b[22:0] != 23'd0);
"""


def add_module():
    """a + b in 3 clocks."""
    name = "float32_add"
    text = f"""// binary32 a + b, round to nearest even, denormals flushed: 3 clocks. Stage 1 orders the operands by magnitude and
// aligns the smaller one's significand to the larger's exponent, keeping a guard, a round and a sticky bit (enough for
// correct rounding: a cancellation of more than one bit only happens when the shift is at most one, which loses
// nothing); stage 2 adds or subtracts and normalises; stage 3 rounds and packs.
module {name} (input wire clk, input wire [31:0] a, input wire [31:0] b, output reg [31:0] sum);
{ROUND_FUNCTION}{CLASSIFY}  wire [30:0] a_magnitude = a_zero ? 31'd0 : a[30:0], b_magnitude = b_zero ? 31'd0 : b[30:0];
  wire swap = b_magnitude > a_magnitude;
  wire [30:0] larger = swap ? b_magnitude : a_magnitude, smaller = swap ? a_magnitude : b_magnitude;
  wire [7:0] distance = larger[30:23] - smaller[30:23];
  wire [53:0] small_shifted = {{smaller[30:23] == 8'd0 ? 24'd0 : {{1'b1, smaller[22:0]}}, 30'd0}} >> (distance > 8'd31 ? 8'd31 : distance);
  // Stage 1.
  reg [26:0] large1, small1;
  reg [7:0] exponent1;
  reg sign1, subtract1, nan1, inf1, inf_sign1, zeros1, zeros_sign1;
  always @(posedge clk) begin
    large1 <= {{1'b1, larger[22:0], 3'd0}};
    small1 <= {{small_shifted[53:28], small_shifted[27] | (small_shifted[26:0] != 27'd0)}};
    exponent1 <= larger[30:23];
    sign1 <= swap ? b[31] : a[31];
    subtract1 <= a[31] ^ b[31];
    nan1 <= a_nan || b_nan || (a_inf && b_inf && a[31] != b[31]);
    inf1 <= a_inf || b_inf;
    inf_sign1 <= a_inf ? a[31] : b[31];
    zeros1 <= a_zero && b_zero;
    zeros_sign1 <= a[31] && b[31];
  end
  // Stage 2: the sum (never negative: the larger magnitude comes first) normalised to a leading one at bit 26.
  wire [27:0] total = subtract1 ? {{1'b0, large1}} - {{1'b0, small1}} : {{1'b0, large1}} + {{1'b0, small1}};
  reg [4:0] leading_zeros;
  integer k;
  always @* begin
    leading_zeros = 5'd27;
    for (k = 0; k < 27; k = k + 1) if (total[k]) leading_zeros = 5'd26 - k;
  end
  reg [26:0] normal2;
  reg signed [11:0] exponent2;
  reg sign2, nan2, inf2, zero2;
  reg [31:0] special2;
  always @(posedge clk) begin
    if (total[27]) begin
      normal2 <= {{total[27:2], total[1] | total[0]}};
      exponent2 <= $signed({{4'd0, exponent1}}) + 12'sd1;
    end else begin
      normal2 <= total[26:0] << leading_zeros;
      exponent2 <= $signed({{4'd0, exponent1}}) - $signed({{7'd0, leading_zeros}});
    end
    sign2 <= sign1;
    nan2 <= nan1;
    inf2 <= inf1;
    // An exact zero: both operands zero (negative only if both are), or x - x (positive, rounding to nearest).
    zero2 <= zeros1 || total == 28'd0;
    special2 <= nan1 ? 32'h{NAN:08x} : inf1 ? {{inf_sign1, 8'hff, 23'd0}} : {{zeros1 && zeros_sign1, 31'd0}};
  end
  // Stage 3.
  always @(posedge clk)
    sum <= (nan2 || inf2 || zero2) ? special2 : float32_round(sign2, exponent2, normal2[26:3], normal2[2], normal2[1] | normal2[0], 1'b0);
endmodule
"""
    return name, text


def mul_module(truncate: bool = False):
    """a * b in 3 clocks; truncate: the deliberately wrong unit that drops the bits below the product's last place."""
    name = "float32_mul_truncating" if truncate else "float32_mul"
    text = f"""// binary32 a * b, {"TRUNCATED (a deliberately wrong multiplier, for the testbench to reject)" if truncate else "round to nearest even"}, denormals flushed: 3 clocks. Stage 1 forms the
// 48-bit significand product, stage 2 normalises it (the leading one at bit 47 or 46), stage 3 rounds and packs.
module {name} (input wire clk, input wire [31:0] a, input wire [31:0] b, output reg [31:0] product);
{ROUND_FUNCTION}{CLASSIFY}  reg [47:0] product1;
  reg signed [11:0] exponent1;
  reg sign1, nan1, inf1, zero1;
  always @(posedge clk) begin
    product1 <= {{1'b1, a[22:0]}} * {{1'b1, b[22:0]}};
    exponent1 <= $signed({{4'd0, a[30:23]}}) + $signed({{4'd0, b[30:23]}}) - 12'sd127;
    sign1 <= a[31] ^ b[31];
    nan1 <= a_nan || b_nan || (a_inf && b_zero) || (b_inf && a_zero);
    inf1 <= a_inf || b_inf;
    zero1 <= a_zero || b_zero;
  end
  reg [23:0] significand2;
  reg guard2, sticky2, sign2, nan2, inf2, zero2;
  reg signed [11:0] exponent2;
  always @(posedge clk) begin
    if (product1[47]) begin
      significand2 <= product1[47:24]; guard2 <= product1[23]; sticky2 <= product1[22:0] != 23'd0; exponent2 <= exponent1 + 12'sd1;
    end else begin
      significand2 <= product1[46:23]; guard2 <= product1[22]; sticky2 <= product1[21:0] != 22'd0; exponent2 <= exponent1;
    end
    sign2 <= sign1; nan2 <= nan1; inf2 <= inf1; zero2 <= zero1;
  end
  always @(posedge clk)
    product <= nan2 ? 32'h{NAN:08x} : inf2 ? {{sign2, 8'hff, 23'd0}} : zero2 ? {{sign2, 31'd0}}
             : float32_round(sign2, exponent2, significand2, guard2, sticky2, 1'b{int(truncate)});
endmodule
"""
    return name, text


def div_module(steps: int):
    """a / b: 26 quotient bits (the integer bit, 23 fraction bits, one more in case the integer bit is 0, a guard)."""
    stages = -(-26 // steps)
    name = f"float32_div_k{steps}"
    L = [f"// binary32 a / b, round to nearest even, denormals flushed: {2 + stages} clocks. Restoring division of the significands",
         f"// (a's over b's, in [1/2, 2)), {steps} quotient bit(s) per stage; the remainder left over is the sticky bit.",
         f"module {name} (input wire clk, input wire [31:0] a, input wire [31:0] b, output reg [31:0] quotient);",
         ROUND_FUNCTION + CLASSIFY.rstrip("\n"),
         "  reg [25:0] r0, q0; reg [23:0] d0; reg signed [11:0] e0; reg s0, nan0, inf0, zero0;",
         "  always @(posedge clk) begin",
         "    r0 <= {2'd0, 1'b1, a[22:0]}; q0 <= 26'd0; d0 <= {1'b1, b[22:0]};",
         "    e0 <= $signed({4'd0, a[30:23]}) - $signed({4'd0, b[30:23]}) + 12'sd127; s0 <= a[31] ^ b[31];",
         "    nan0 <= a_nan || b_nan || (a_inf && b_inf) || (a_zero && b_zero);",
         "    inf0 <= (a_inf && !b_inf) || (b_zero && !a_zero); zero0 <= (a_zero && !b_zero) || (b_inf && !a_inf);",
         "  end"]
    bit = 25
    for s in range(1, stages + 1):
        p = s - 1
        L.append(f"  reg [25:0] r{s}, q{s}; reg [23:0] d{s}; reg signed [11:0] e{s}; reg s{s}, nan{s}, inf{s}, zero{s};")
        L.append(f"  always @(posedge clk) begin : stage{s}")
        L.append("    reg [25:0] r, q;")
        L.append(f"    r = r{p}; q = q{p};")
        for _ in range(steps):
            if bit < 0:
                break
            if bit < 25:
                L.append("    r = {r[24:0], 1'b0};")  # the next dividend bit is a zero (the dividend is a's significand)
            L.append(f"    if (r >= {{2'd0, d{p}}}) begin r = r - {{2'd0, d{p}}}; q[{bit}] = 1'b1; end")
            bit -= 1
        L.append(f"    r{s} <= r; q{s} <= q; d{s} <= d{p}; e{s} <= e{p}; s{s} <= s{p}; nan{s} <= nan{p}; inf{s} <= inf{p}; zero{s} <= zero{p};")
        L.append("  end")
    z = stages
    L += ["  // The quotient's leading one is at bit 25 (a's significand at least b's) or 24 (one exponent less).",
          "  always @(posedge clk)",
          f"    quotient <= nan{z} ? 32'h{NAN:08x} : inf{z} ? {{s{z}, 8'hff, 23'd0}} : zero{z} ? {{s{z}, 31'd0}}",
          f"              : q{z}[25] ? float32_round(s{z}, e{z}, q{z}[25:2], q{z}[1], q{z}[0] || r{z} != 26'd0, 1'b0)",
          f"              : float32_round(s{z}, e{z} - 12'sd1, q{z}[24:1], q{z}[0], r{z} != 26'd0, 1'b0);",
          "endmodule", ""]
    return name, "\n".join(L)


def sqrt_module(steps: int):
    """sqrt(a): 25 root bits (24 and a guard) of the significand shifted to an even exponent."""
    stages = -(-25 // steps)
    name = f"float32_sqrt_k{steps}"
    L = [f"// binary32 sqrt(a), round to nearest even, denormals flushed: {2 + stages} clocks. The significand, shifted left by 25 or",
         "// 26 bits so that the exponent left is even, has a 25-bit integer root (the leading one at bit 24), found two",
         f"// radicand bits per digit, {steps} digit(s) per stage; the remainder left over is the sticky bit. sqrt(-0) is -0,",
         "// a negative number gives NaN.",
         f"module {name} (input wire clk, input wire [31:0] a, output reg [31:0] root);",
         ROUND_FUNCTION.rstrip("\n"),
         "  wire a_zero = (a[30:23] == 8'd0), a_inf = (a[30:23] == 8'hff) && (a[22:0] == 23'd0), a_nan = (a[30:23] == 8'hff) && (a[22:0] != 23'd0);",
         "  // An odd unbiased exponent (an even biased one) moves one bit into the radicand.",
         "  wire [49:0] radicand = a[23] ? {1'b0, 1'b1, a[22:0], 25'd0} : {1'b1, a[22:0], 26'd0};",
         "  wire [8:0] exponent_sum = {1'b0, a[30:23]} + 9'd127;",
         "  reg [49:0] v0; reg [27:0] rem0; reg [24:0] q0; reg [7:0] e0; reg s0, nan0, inf0, zero0;",
         "  always @(posedge clk) begin",
         "    v0 <= radicand; rem0 <= 28'd0; q0 <= 25'd0; e0 <= exponent_sum[8:1]; s0 <= a[31];",
         "    nan0 <= a_nan || (a[31] && !a_zero); inf0 <= a_inf && !a[31]; zero0 <= a_zero;",
         "  end"]
    digit = 24
    for s in range(1, stages + 1):
        p = s - 1
        left = max(digit + 1 - steps, 0)  # radicand digits still to come after this stage: only those travel on
        L.append(f"  reg [27:0] rem{s}; reg [24:0] q{s}; reg [7:0] e{s}; reg s{s}, nan{s}, inf{s}, zero{s};"
                 + (f" reg [{2 * left - 1}:0] v{s};" if left else ""))
        L.append(f"  always @(posedge clk) begin : stage{s}")
        L.append("    reg [27:0] rem, trial; reg [24:0] q;")
        L.append(f"    rem = rem{p}; q = q{p};")
        for _ in range(steps):
            if digit < 0:
                break
            L.append(f"    rem = {{rem[25:0], v{p}[{2 * digit + 1}:{2 * digit}]}};")
            L.append("    trial = {1'b0, q, 2'b01};")
            L.append("    if (rem >= trial) begin rem = rem - trial; q = {q[23:0], 1'b1}; end else q = {q[23:0], 1'b0};")
            digit -= 1
        L.append((f"    v{s} <= v{p}[{2 * left - 1}:0];" if left else "") + f" rem{s} <= rem; q{s} <= q; e{s} <= e{p}; s{s} <= s{p}; nan{s} <= nan{p}; inf{s} <= inf{p}; zero{s} <= zero{p};")
        L.append("  end")
    z = stages
    L += ["  always @(posedge clk)",
          f"    root <= nan{z} ? 32'h{NAN:08x} : inf{z} ? {{1'b0, 8'hff, 23'd0}} : zero{z} ? {{s{z}, 31'd0}}",
          f"          : float32_round(1'b0, $signed({{4'd0, e{z}}}), q{z}[24:1], q{z}[0], rem{z} != 28'd0, 1'b0);",
          "endmodule", ""]
    return name, "\n".join(L)
