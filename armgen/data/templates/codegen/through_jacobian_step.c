  ${p}_real J[6 * ${P}_NDOF];
  ${p}_status status;
  ${p}_jacobian(q, J);
  status = ${p}_${twin}($arguments);
  {
$probe
  return (probe == probe) ? status : ${P}_NONFINITE;
  }
