/* joint $quantity limits, rad or m per $per */
#define ${P}_$macro { $limits }
