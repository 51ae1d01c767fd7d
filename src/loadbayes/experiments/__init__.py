"""The paper's studies and the comparisons, as functions returning tables and figures."""
