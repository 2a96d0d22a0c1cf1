  /* a target that is not a pose takes no step (the loop stops before its first) */
  const int pose = ${p}_is_pose(T_target);
  const ${p}_real $cap = (pose != 0) ? max_iterations : ${P}_LIT(0.0);
$body
  if (pose == 0) { return ${P}_BAD_TARGET; }
  {
$probe
  if (probe != probe) { return ${P}_NONFINITE; }
  }
  return (*success != ${P}_LIT(0.0)) ? ${P}_OK : ${P}_NOT_CONVERGED;
