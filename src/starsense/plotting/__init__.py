"""Figures, one module per analysis: functions take ``ax=`` and return the figure."""
