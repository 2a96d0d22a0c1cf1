#define ${P}_${FUNCTION}_WORK_REALS $work_reals
$signature;
