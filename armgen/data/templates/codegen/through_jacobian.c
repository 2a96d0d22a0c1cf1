  ${p}_real J[6 * ${P}_NDOF];
  ${p}_jacobian(q, J);
  ${p}_${twin}($arguments);
