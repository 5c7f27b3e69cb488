; saxpy: z[i] = 2.5 * x[i] + y[i] (fp32), a software-pipelined loop: a new iteration
; starts every 2 cycles (II = 2) and each iteration spans 5 stages (10 cycles).
;
; Schedule of one iteration (cycle = 2 * stage + instruction):
;   t0  sin0 x           -> mul0.b[0]   lands t3
;   t4  mul0 fmul        -> add0.a[0]   lands t8
;   t5  sin1 y           -> add0.b[0]   lands t8
;   t9  add0 fadd        -> stream z    lands t13
; Every value is read 1 cycle after it lands (t3 -> t4, t8 -> t9) and before the next
; iteration's copy lands 2 cycles later, whether a result is readable in its landing cycle
; or only in the next. The microcontroller squashes stage s in pass p unless
; s <= p < N + s, so the 4 prologue and epilogue passes need no extra code.
kernel saxpy
in x
in y
out z

    imm 2.5 -> mul0.a[0]                                    ; the constant a
loop stream x, stages 5:
    sin0 x -> mul0.b[0] | mul0 fmul a[0], b[0] -> add0.a[0] @2
    sin1 y -> add0.b[0] @2 | add0 fadd a[0], b[0] -> stream z @4
end
done
