"""Running measurements: one config's experiment (experiment), two sides measured together
(pair, with the sides' builds in sides), and what every command shares (command)."""
