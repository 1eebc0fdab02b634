"""Sewing patterns: flat panels cut from cloth and the seams that join them.

``model`` holds the pattern as read (panels in metres of the pattern, their edges as curves, the stitches);
``curves`` evaluates an edge. Readers for each file format build a ``model.Pattern`` and nothing else reads files.
"""
