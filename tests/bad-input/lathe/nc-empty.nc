(nothing)
