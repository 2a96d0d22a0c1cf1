#define ${P}_$macro $function
