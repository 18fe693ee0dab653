"""The report's figures: each a pure function from a DataFrame to the files it wrote (base says
how), one module per kind of figure."""
