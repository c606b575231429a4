"""`make mutate`'s realistic operators (tools/mutate_operators.py) on small C++ snippets, and the
cheap checks that keep mutants that cannot compile out of the sample (mutate_mutants.plausible)."""

from __future__ import annotations

import sys
from pathlib import Path

TOOLS = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(TOOLS))
import mutate_mutants  # noqa: E402
import mutate_operators as ops  # noqa: E402

SNIPPET = """\
namespace joint {
// a comment that says a && b
float Gate::update(float speed, float limit, int count) {
  const float margin = limit * 0.001F;
  if (std::fabs(speed) >= limit && count > 3) {
    cycles_ = 0;
  }
  if (ready_ &&
      speed < margin) return State::kRunning;
  const char* text = "x && y";
  return speed * 1000;
}
}  // namespace joint
"""


def mutants(rule: str, text: str = SNIPPET, index: ops.ProjectIndex | None = None) -> dict[int, list[str]]:
    found: dict[int, list[str]] = {}
    members = [("int", "cycles_"), ("int", "count_")]
    for line, replacement, used in ops.realistic_mutants(text, "firmware/joint/Gate.cpp", index, members):
        if used == rule:
            found.setdefault(line, []).append(replacement.strip())
    return found


def test_a_condition_is_dropped_from_a_conjunction_one_operand_at_a_time() -> None:
    dropped = mutants("drop condition")
    assert dropped[5] == ["if (count > 3) {", "if (std::fabs(speed) >= limit) {"]
    assert dropped[8] == ["if ("], "an operand going on to the next line is dropped from its own side only"
    assert 2 not in dropped and 10 not in dropped, "comments and strings are not code"


def test_an_absolute_value_is_lost_and_a_bound_moves_to_its_neighbour() -> None:
    assert mutants("abs removed")[5] == ["if ((speed) >= limit && count > 3) {"]
    assert mutants("bound")[5] == [
        "if (std::fabs(speed) > limit && count > 3) {",
        "if (std::fabs(speed) >= limit && count >= 3) {",
    ]
    assert mutants("bound")[9] == ["speed <= margin) return State::kRunning;"]
    template = "void f() {\n  std::array<int, 3> a{};\n  auto b = static_cast<float>(a[0]);\n}\n"
    assert mutants("bound", template) == {}, "a template's angle brackets are no comparison"


def test_a_unit_is_off_by_a_factor_of_1000_either_way() -> None:
    scaled = mutants("unit scale x1000")
    assert scaled[4] == ["const float margin = limit * 1.0F;", "const float margin = limit * 1e-06F;"]
    assert scaled[11] == ["return speed * 1000000;", "return speed * 1;"]


def test_a_variable_is_replaced_by_another_of_its_type_in_scope() -> None:
    swapped = mutants("same-type variable")
    assert "if (std::fabs(speed) >= margin && count > 3) {" in swapped[5]
    assert "speed < speed) return State::kRunning;" not in swapped[9], "x < x does not compile (-Werror)"
    assert "speed < limit) return State::kRunning;" in swapped[9]
    assert "if (std::fabs(speed) >= limit && cycles_ > 3) {" in swapped[5], "a member of the same type"
    assert not any("count >= " in m or "(count)" in m for m in swapped[5]), "never one of another type"
    assert 4 not in swapped or all("margin =" in m for m in swapped[4]), "a declaration keeps its name"
    outside = "int global = 1;\nint other = global;\n"
    assert mutants("same-type variable", outside) == {}, "only in a function's body"


def test_a_reset_or_assignment_is_deleted() -> None:
    assert mutants("statement deleted") == {6: [";"]}


def test_a_named_constant_is_replaced_by_a_neighbour_of_its_enum_or_header() -> None:
    index = ops.ProjectIndex()
    index.add(
        "firmware/joint/State.hpp",
        "enum class State { kIdle, kRunning, kFault, kDone, kLast };\n"
        "constexpr float kWarn = 1.0F;\nconstexpr float kTrip = 2.0F;\nconstexpr int kCount = 3;\n",
    )
    assert mutants("sibling constant", index=index)[9] == [
        "speed < margin) return State::kIdle;",
        "speed < margin) return State::kFault;",
        "speed < margin) return State::kDone;",
    ]
    use = "bool f(float t) {\n  return t > kWarn;\n}\n"
    assert mutants("sibling constant", use, index) == {2: ["return t > kTrip;"]}, "same type only"


def test_the_scope_model_finds_function_bodies_not_classes_or_initialisers() -> None:
    text = (
        "namespace a {\nstruct S {\n  int x_ = 0;\n  int get() const { return x_; }\n};\n"
        "constexpr int kTable[] = {1, 2};\nS::S(int v) : x_{v} {\n  x_ = v;\n}\n}\n"
    )
    functions = ops.functions_of(ops.code_lines(text.splitlines(keepends=True)))
    assert [(f.first, f.last) for f in functions] == [(4, 4), (7, 9)]


def plausible(
    original: str, replacement: str, before: str = "void f() {\n", after: str = "}\n", rule: str = ""
) -> bool:
    text = before + original + after
    code = ops.code_lines(text.splitlines(keepends=True))
    functions = ops.functions_of(code)
    line = before.count("\n") + 1
    return mutate_mutants.plausible(code, functions, line, original, replacement, rule)


def test_mutants_that_cannot_compile_are_not_generated() -> None:
    assert not plausible("  auto x = static_cast<float>(y);\n", "  auto x = static_cast<=float>(y);\n")
    assert not plausible("  g(a, b);\n", "  g(a, b;\n"), "brackets unbalanced"
    assert not plausible("  const int n = 3;\n", "  /*const int n = 3;*/\n"), "a declaration's name is used"
    assert not plausible("  return x;\n", "  /*return x;*/\n"), "the last return: -Werror=return-type"
    assert not plausible("      b);\n", "      /*b);*/\n", "void f() {\n  g(a,\n"), (
        "a statement's continuation"
    )
    assert not plausible("int x_ = 0;\n", "/*int x_ = 0;*/\n", "struct S {\n", "};\n"), "not in a body"
    assert not plausible("  h(std::uint32_t{5});\n", "  h(std::uint(32+1)_t{5});\n")
    assert plausible("  count = 0;\n", "  /*count = 0;*/\n")
    assert plausible("  if (a < b) g();\n", "  if (a <= b) g();\n")
    assert not plausible("  x = index >> 8;\n", "  x = index <=> 8;\n"), "no operator"
    assert not mutants(
        "sibling constant", "void f(State s) {\n  switch (s) {\n    case State::kIdle: break;\n  }\n}\n"
    )


def test_break_and_continue_are_added_only_in_a_loop() -> None:
    loop = "void f() {\n  for (int i = 0; i < 3; ++i) {\n"
    assert plausible("    g(i);\n", "    g(i);\n    continue;\n", loop, "  }\n}\n")
    assert not plausible("  g(1);\n", "  g(1);\n  continue;\n"), "no loop around it"
    switch = "void f(int s) {\n  switch (s) {\n    case 1:\n"
    assert plausible("      g(1);\n", "      g(1);\n      break;\n", switch, "  }\n}\n")
    assert not plausible("      g(1);\n", "      g(1);\n      continue;\n", switch, "  }\n}\n")


def test_more_mutants_that_cannot_compile_are_not_generated() -> None:
    assert not plausible("  x = now - last;\n", "  x = now  last;\n"), "a binary operator removed"
    assert not plausible("  ++count;\n", "  +%count;\n")
    assert plausible("  ++count;\n", "  --count;\n")
    assert not plausible('  s = a + ": " + b;\n', '  s = a - ": " + b;\n'), "a string's concatenation"
    swap = r"([,\(\[\{])([^=,\)\}\]]+),([^=,\)\}\]]+)([,\)\]\}]) ==>  \1\3,\2\4"
    assert not plausible("  auto f = [](int a, float b) {\n", "  auto f = [](float b,int a) {\n", rule=swap)
    assert plausible("  g(a, b);\n", "  g( b,a);\n", rule=swap), "a call's arguments swapped"
    unused = "void f(int now) {\n  g();\n  last_ = now;\n}\n"
    assert not mutants("statement deleted", unused), "its parameter would be left unused"
    forced = r"if (\(.*\)) ==> if (0==1)"
    assert not plausible("  if (ok) g(1);\n", "  if (0==1);\n", rule=forced), "the statement went too"
    assert plausible("  if (ok) g(1);\n", "  if (0==1) g(1);\n", rule=forced)
    assert not plausible("  g(Kind::VendorId);\n", "  g(Kind::VbeginorId);\n"), "part of a name"
    assert plausible("  g(v.end());\n", "  g(v.begin());\n")
    assert not plausible("};\n", "/*};*/\n", "void f() {\n  auto x = S{\n", "}\n"), "a brace's statement"
    sibling = plausible(
        "  g(FieldId::thermal_warning_c);\n", "  g(FieldId::thermal_limit_c);\n", rule="sibling constant"
    )
    assert sibling, "a sibling constant is a whole name"
