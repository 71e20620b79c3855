"""The live path: the datagrams the sensors of a ship send (Kongsberg .kmall, NMEA 0183), sent from a recording and received."""
