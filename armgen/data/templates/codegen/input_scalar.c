${p}_real $name
