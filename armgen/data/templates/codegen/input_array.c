const ${p}_real $name[$size]
