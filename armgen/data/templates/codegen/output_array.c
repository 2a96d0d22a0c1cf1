${p}_real $name[$size]
