#!/usr/bin/env bash
# Fails when a Catch2 test name holds ';' or is split into adjacent literals: the Cobalt preset registers tests from their sources
# (VIGIL_TEST_DISCOVERY=sources) and CTest cannot name a test with ';', so its configure fails.
# Run by CTest (test_names) in every build, so that such a name is caught where it is written.
root="$(cd "$(dirname "$0")/.." && pwd)"
if grep -rn -E 'TEST_CASE\("[^"]*;' "$root/tests" --include='*.cpp'; then
  echo "check-test-names: the test names above hold ';' (not allowed: see cmake/VigilCatchTests.cmake)" >&2
  exit 1
fi
# A name written as adjacent literals ("a " "b") is not understood by that parser either.
if grep -rlPz 'TEST_CASE\(\s*"[^"\n]*"\s*"' "$root/tests" --include='*.cpp'; then
  echo "check-test-names: the files above write a test name as several string literals (one literal, please: see cmake/VigilCatchTests.cmake)" >&2
  exit 1
fi
echo "check-test-names: no test name holds ';' or is split into several literals"
