void ${p}_$loop($parameters, ${p}_real final[$size])
