// Product code of another target (not in this tree's CMakeLists.txt, as the bare-metal firmware is
// not in the host build): its mutants would pass every test unmutated, so none is sampled.
int other_target_scale(int value) { return value * 7; }
