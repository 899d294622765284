"""Input and output: model files (safe TOML + expression parser), text/LaTeX/JSON printing,
the HTML report and the command line.
"""
