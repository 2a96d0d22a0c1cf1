  {
$probe
  return (probe == probe) ? ${P}_OK : ${P}_NONFINITE;
  }
