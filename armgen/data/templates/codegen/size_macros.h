#define ${P}_${function}_${argument}_ROWS $rows
#define ${P}_${function}_${argument}_COLS $cols
