/* no ${P}_$macro: the robot file gives no joint $quantity limit for every joint */
