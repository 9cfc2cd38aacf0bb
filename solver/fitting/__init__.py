"""The fit: the views of a case, the joint solve of head and cameras, the thesis' stages and
approaches, and what a fit returns. ``fit.py`` composes them (``fit_head``,
``refit_landmarks``); the shape-ICP, its rows and the 3-D registration are the tools."""
